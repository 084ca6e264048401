// A bonded dimer relaxes as the scalar ODE of its bond length says.
//
// Derivation (independent of the plugin's code). Two beads at x0, x1 = x0 + r u, joined by
// OpenMM's HarmonicBondForce, energy k/2 (r - r0)^2: the force on bead 1 is F = -k (r - r0) u
// and on bead 0 it is -F. With the RPY mobility (shared/model.md),
//   v1 = mu_11 F + mu_10 (-F) = (mu0 - mu_par(r)) F,   v0 = -(mu0 - mu_par(r)) F,
// where mu_par(r) = u . mu_01 . u is the pair mobility along the axis:
//   r >= d:  mu_par = mu0 3d/(8r) [(1 + d^2/(6r^2)) + (1 - d^2/(2r^2))] = mu0 (3d/(4r) - d^3/(8r^3)),
//   r <  d:  mu_par = mu0 [(1 - 9r/(16d)) + 3r/(16d)]                    = mu0 (1 - 3r/(8d)).
// (Both give 5/8 mu0 at r = d, and both have slope -3/8 mu0/d there: value and first
// derivative are continuous.) Hence, with both beads staying on the line by symmetry,
//   dr/dt = u . (v1 - v0) = -2 k (r - r0) (mu0 - mu_par(r)),
// and the centre of mass does not move (v0 + v1 = 0).
//
// Checks (Reference platform; all cases with the bond along the skew direction (1,2,2)/3):
//   1. rk23 (tolerance 1e-10 nm) through stepTo(t) at t = 0.05 .. 0.8 against the ODE
//      integrated here by classical RK4 with dt = 1e-5 (its own error is < 1e-13), for a bond
//      wholly in the far field (d = 1, r0 = 2, r: 3.5 -> 2), one that crosses into the overlap
//      region (r0 = 0.6 d, r: 1.6 -> 0.6), and one with d = 1.3, mu0 = 0.7 (mobility and
//      diameter settings). Tolerance 2e-8 nm: rk23 keeps each step's local error below 1e-10
//      nm and the relaxation contracts earlier errors, so the global error stays near the
//      tolerance (measured ~1.4e-10 nm over ~2000 steps); 2e-8 leaves room for another
//      sequence of step sizes, not for a wrong mobility (a 1e-3 relative error in mu_par moves
//      r by > 1e-4 nm here). Also rkc2 (tolerance 1e-8, bound 5e-6 nm; measured 1.5e-6, it
//      is second order), the beads stay on the axis and the centre of mass stays put
//      (1e-12 nm) at every check.
//   2. Order of the fixed-step methods: the error at t = 0.4 for h = 0.01 and h = 0.005 drops
//      by 2 (euler, order 1: ratio in [1.8, 2.2]) or by 4 (heun, midpoint, order 2:
//      [3.5, 4.5]).
//   3. Linear regime: from r = r0 + 1e-5, r - r0 decays as exp(-lambda t) with the closed form
//      lambda = 2 k (mu0 - mu_par(r0)); the measured rate -ln(dr(t)/dr(0))/t (rk23 at
//      tolerance 1e-13, to lambda t = 2) agrees to 1e-4 relative: the nonlinear correction is
//      ~ |mu_par'(r0)| dr / (mu0 - mu_par(r0)) <= 1.7e-5 (overlap region), in the
//      far field (r0 = 2: lambda = 2k (1 - 23/64)) and in the overlap region (r0 = 0.6:
//      lambda = 2k (3 r0 / 8)).

#include "TestUtilities.h"

using namespace OpenMM;
using namespace knotmm_test;

namespace {

struct Dimer {
    double d, mu0, k, r0;
};

/** mu_par(r) / mu0 from the closed form above. */
double parallelMobility(double r, double d) {
    return r >= d ? 3.0 * d / (4.0 * r) - d * d * d / (8.0 * r * r * r) : 1.0 - 3.0 * r / (8.0 * d);
}

double rate(const Dimer& p, double r) {
    return -2.0 * p.k * (r - p.r0) * p.mu0 * (1.0 - parallelMobility(r, p.d));
}

/** r(t) by classical RK4 with a fixed step, from r(0) = r. */
double odeSolution(const Dimer& p, double r, double t) {
    const int steps = (int) std::ceil(t / 1e-5);
    const double dt = t / steps;
    for (int i = 0; i < steps; i++) {
        const double a = rate(p, r);
        const double b = rate(p, r + 0.5 * dt * a);
        const double c = rate(p, r + 0.5 * dt * b);
        const double e = rate(p, r + dt * c);
        r += dt / 6.0 * (a + 2.0 * b + 2.0 * c + e);
    }
    return r;
}

const Vec3 AXIS = Vec3(1.0, 2.0, 2.0) / 3.0;
const Vec3 CENTRE(0.3, -0.2, 0.1);

struct Run {
    System system;
    KnotMM::RPYIntegrator* integrator;
    Context* context;
    Run(const Dimer& p, double r, const std::string& method, double hOrTol) {
        system.addParticle(1.0);
        system.addParticle(1.0);
        HarmonicBondForce* bond = new HarmonicBondForce();
        bond->addBond(0, 1, p.r0, p.k);
        system.addForce(bond);
        const bool adaptive = method == "rk23" || method == "rkc2";
        integrator = new KnotMM::RPYIntegrator(adaptive ? 1e-3 : hOrTol, method, adaptive ? hOrTol : 1e-4);
        integrator->setBeadDiameter(p.d);
        integrator->setMobility(p.mu0);
        context = makeContext(system, *integrator, "Reference");
        context->setPositions({CENTRE - AXIS * (0.5 * r), CENTRE + AXIS * (0.5 * r)});
    }
    ~Run() {
        delete context;
        delete integrator;
    }
    /** Bond length; checks that the beads are on the axis through CENTRE. */
    double length(const std::string& label) {
        const std::vector<Vec3> x = positionsOf(*context);
        const Vec3 sep = x[1] - x[0];
        const Vec3 mid = (x[0] + x[1]) * 0.5;
        const Vec3 off = sep.cross(AXIS);
        checkAbs(label + ": off-axis", 0.0, std::sqrt(off.dot(off)), 1e-12, where(__FILE__, __LINE__), true);
        checkAbs(label + ": centre of mass", 0.0, std::sqrt((mid - CENTRE).dot(mid - CENTRE)), 1e-12,
                 where(__FILE__, __LINE__), true);
        return sep.dot(AXIS);
    }
};

void compareWithOde(const std::string& name, const Dimer& p, double r, const std::string& method,
                    double tol, double bound) {
    Run run(p, r, method, tol);
    double worst = 0.0;
    for (double t : {0.05, 0.1, 0.2, 0.4, 0.8}) {
        run.integrator->stepTo(t);
        const double expected = odeSolution(p, r, t);
        const double found = run.length(name);
        worst = std::max(worst, checkAbs(name + " " + method + " r(t=" + std::to_string(t) + ")", expected,
                                         found, bound, where(__FILE__, __LINE__), true));
    }
    std::printf("  %-58s largest |r - r_ode| %.3g nm (tol %.3g), %lld steps\n", (name + " " + method).c_str(),
                worst, bound, run.integrator->getNumAcceptedSteps());
}

double fixedStepError(const Dimer& p, double r, const std::string& method, double h) {
    Run run(p, r, method, h);
    run.integrator->stepTo(0.4);
    return std::fabs(run.length(method) - odeSolution(p, r, 0.4));
}

void checkLinearRate(const std::string& name, const Dimer& p) {
    const double delta = 1e-5;
    const double lambda = 2.0 * p.k * p.mu0 * (1.0 - parallelMobility(p.r0, p.d));
    const double t = 2.0 / lambda;
    Run run(p, p.r0 + delta, "rk23", 1e-13);
    run.integrator->stepTo(t);
    const double measured = -std::log((run.length(name) - p.r0) / delta) / t;
    KT_CHECK_REL(name + ": relaxation rate lambda = 2k(mu0 - mu_par(r0))", lambda, measured, 1e-4);
}

} // namespace

int main() {
    return runTest("TestRPYDimerRelaxation: bond length against dr/dt = -2k(r-r0)(mu0-mu_par(r))", [] {
        const Dimer far = {1.0, 1.0, 5.0, 2.0}, overlap = {1.0, 1.0, 5.0, 0.6}, scaled = {1.3, 0.7, 8.0, 1.0};
        compareWithOde("far field", far, 3.5, "rk23", 1e-10, 2e-8);
        compareWithOde("into overlap", overlap, 1.6, "rk23", 1e-10, 2e-8);
        compareWithOde("d=1.3 mu0=0.7", scaled, 2.4, "rk23", 1e-10, 2e-8);
        compareWithOde("far field", far, 3.5, "rkc2", 1e-8, 5e-6);
        compareWithOde("into overlap", overlap, 1.6, "rkc2", 1e-8, 5e-6);

        // order of convergence of the fixed-step methods (far field, r: 3.5 -> 2)
        const struct {
            const char* method;
            double low, high;
        } orders[] = {{"euler", 1.8, 2.2}, {"heun", 3.5, 4.5}, {"midpoint", 3.5, 4.5}};
        for (const auto& o : orders) {
            const double e1 = fixedStepError(far, 3.5, o.method, 0.01);
            const double e2 = fixedStepError(far, 3.5, o.method, 0.005);
            std::printf("  %-58s error(h=0.01) %.3g error(h=0.005) %.3g ratio %.4f (want [%.1f, %.1f])\n",
                        o.method, e1, e2, e1 / e2, o.low, o.high);
            KT_ASSERT(e1 / e2 >= o.low && e1 / e2 <= o.high);
        }

        checkLinearRate("far field r0 = 2", far);
        checkLinearRate("overlap r0 = 0.6", overlap);
    });
}
