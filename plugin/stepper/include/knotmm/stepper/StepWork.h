#ifndef KNOTMM_STEPPER_STEP_WORK_H_
#define KNOTMM_STEPPER_STEP_WORK_H_

// What every method's step works on: the backend, the Context, the state at the step's start
// and the velocity cached there, the noise stream and the counters.

#include "knotmm/RPYMethods.h"
#include "knotmm/stepper/Backend.h"
#include "knotmm/stepper/NoiseStream.h"

#include <map>
#include <string>

namespace KnotMM {

/** A velocity and the positions and Context parameters it was computed at (FSAL). */
struct VelocityCache {
    VectorPtr v, positions;
    std::map<std::string, double> parameters;
    bool valid = false;
};

struct StepCounts {
    long long evaluations = 0, accepted = 0, rejected = 0;
};

class StepWork {
public:
    StepWork(RPYBackend& backend, RPYMethod method);
    RPYBackend& backend;
    RPYMethod method;
    OpenMM::ContextImpl* context = nullptr;  // set for each step
    RPYIntegrator* integrator = nullptr;     // set for each step
    double kT = 0.0;
    double t0 = 0.0;  // the step's start time (ps), set for each step
    VectorPtr y, y1;  // the step's start and end
    VelocityCache k1;  // velocity at y
    StepCounts counts;
    NoiseStream noise;
    VectorPtr xi;  // scratch: standard normals

    /** v = mu(at) F(at): one force evaluation. */
    void velocity(const StateVector& at, StateVector& v);
    /** k1.v is the velocity at `at` with the Context's current parameters. */
    void keepVelocity(const StateVector& at);
    /** out = scale B(at) xi, xi fresh normals; scale == 0 gives zeros and draws nothing. */
    void noiseSample(const StateVector& at, double scale, StateVector& out);
    /**
     * Largest per-bead norm of `err` over `tolerance`; +infinity if anything is not finite.
     * Checks y1 for non-finite numbers in the same call (y1NonFinite): call it after y1 is made.
     */
    double errorRatio(const StateVector& err, double tolerance);
    /** firstNonFinite(y1) as the last errorRatio found it; -2: not checked in this step. */
    int y1NonFinite = -2;
    /**
     * An adaptive method's rejected try: count it and set the next step to `next` (ps); below
     * the integrator's minimum step, throw RPYStepFault (StepUnderflow) with the error ratio
     * `error` and the message ending in `tail`.
     */
    void reject(double next, double error, const char* tail);
    /** The method's name (messages). */
    const char* name() const { return rpyMethodInfo(method).name; }
};

} // namespace KnotMM

#endif
