#ifndef KNOTMM_RPY_METHODS_H_
#define KNOTMM_RPY_METHODS_H_

// The plugin's method table: every integration method RPYIntegrator knows, in one place.
// RPYIntegrator validates names against it, the stepper dispatches on its ids (whose values
// are part of the checkpoint layout: never renumber), and the Python module exports it
// (rpyplugin.methodTable()), which knotmm.plugin.METHODS is built from; a test holds
// knotmm.dynamics.registry to it.

#include <string>
#include <vector>

namespace KnotMM {

/** Method ids; the values are written into checkpoints. */
enum class RPYMethod : int {
    Euler = 0,
    Heun = 1,
    Midpoint = 2,
    RK23 = 3,
    RKC2 = 4,
    EulerMaruyama = 5,
    ItoHeun = 6,
    LeimkuhlerMatthews = 7,
    ItoHeunAdaptive = 8,
};

struct RPYMethodInfo {
    RPYMethod id;
    const char* name;   // the name RPYIntegrator takes (knotmm's run.integrator)
    int order;          // order of accuracy (Brownian: weak order)
    bool adaptive;      // the step size follows error control
    bool stochastic;    // integrates the Ito equation with noise when kT > 0
                        // (ito_heun_adaptive is both: adaptive and stochastic)
};

/** Every method, in the order of their ids. */
const std::vector<RPYMethodInfo>& rpyMethodTable();

/** The entry named `name`; OpenMM::OpenMMException listing the names if there is none. */
const RPYMethodInfo& rpyMethodInfo(const std::string& name);

/** The entry with id `id`. */
const RPYMethodInfo& rpyMethodInfo(RPYMethod id);

/** "euler, heun, ..." (for messages). */
std::string rpyMethodNames();

/**
 * The landing rule: a time within landingSlack(t) = 1e-9 max(1, |t|) of a target t counts as
 * reached (stepTo stops there; the step that gets there lands exactly on t). knotmm's Python
 * engine uses the same rule (knotmm.engine.schedule).
 */
double landingSlack(double target);

} // namespace KnotMM

#endif
