// One bead under a constant external force F moves at v = mu0 F, exactly.
//
// Why this is independent: with a single bead the mobility is mu_11 = mu0 I (no pairs), and
// a constant force makes every Runge-Kutta stage equal, so every method (each a consistent
// one-step scheme whose weights sum to 1) must give x(t) = x(0) + mu0 F t up to rounding,
// whatever the step size and the adaptive controller do. The Brownian methods at kT = 0 have
// no noise and reduce to euler / heun (leimkuhler_matthews: euler), same result.
//
// Checks, for euler, heun, midpoint, rk23, rkc2, euler_maruyama, ito_heun and
// leimkuhler_matthews (kT = 0), on Reference (and CPU, OpenCL in mixed precision when they
// load; OpenCL's force arrives in 64-bit fixed point, within 2^-32 of F, so there
// 1e-12 + mu0 2^-32 t is allowed):
//   * step(n): z after n steps of h equals z0 + mu0 F n h (1e-12 nm; fixed methods: the
//     elapsed time is n h; adaptive ones grow the step, 5x a step up to the 1 ps maximum, and
//     the elapsed time is read back);
//   * then, positions, time and step size set back, stepTo(T): the Context's time is exactly T
//     and z = z0 + mu0 F T (1e-12 nm);
//   * x and y do not move (1e-14 absolute).
// mu0 = 0.7 (not 1) so that the mobility setting is checked to scale velocities; the force
// is the CustomExternalForce "-f*z" (force +f along z), with f = 1.3125 a per-particle
// parameter (OpenMM's device platforms store per-particle parameters in single precision,
// even in double precision: 21/16 is exact there, 1.3 would be off by 4e-8), on a bead
// started far from the origin (the plugin shifts positions to the centre of mass before
// evaluating forces; a constant force does not care).

#include "TestUtilities.h"

using namespace OpenMM;
using namespace knotmm_test;

namespace {

const double MU0 = 0.7, FORCE = 1.3125;

void checkPosition(const std::string& label, const std::string& platform, const Vec3& start, double t,
                   const Vec3& x) {
    // a device platform hands the force over in 64-bit fixed point: F within 2^-32 (truncated)
    const double bound = 1e-12 + (isDevice(platform) ? MU0 * std::ldexp(1.0, -32) * t : 0.0);
    KT_CHECK_ABS(label + ": z = z0 + mu0 F t", start[2] + MU0 * FORCE * t, x[2], bound);
    KT_CHECK_ABS(label + ": x unchanged", start[0], x[0], 1e-14);
    KT_CHECK_ABS(label + ": y unchanged", start[1], x[1], 1e-14);
}

/** step(25), then (positions, time and step size set back) stepTo(0.7371), in one Context. */
void fall(const std::string& platform, const std::string& method) {
    System system;
    system.addParticle(1.0);
    CustomExternalForce* field = new CustomExternalForce("-f*z");
    field->addPerParticleParameter("f");
    field->addParticle(0, {FORCE});
    system.addForce(field);

    const double h = 0.01;
    KnotMM::RPYIntegrator integrator(h, method, 1e-6);
    integrator.setMobility(MU0);
    integrator.setRandomNumberSeed(7);
    const Vec3 start(3.0, -2.0, 40.0);
    Context* context = makeContext(system, integrator, platform);
    context->setPositions({start});

    const int n = 25;
    integrator.step(n);
    // adaptive methods grow the step (the error estimate is 0): the elapsed time is
    // whatever they took; it is read back and checked against the fixed-step value.
    double t = context->getState(State::Positions).getTime();
    if (!integrator.isAdaptive())
        KT_CHECK_REL(platform + " " + method + " elapsed time of 25 steps", n * h, t, 1e-14);
    KT_ASSERT(integrator.getNumAcceptedSteps() == n);
    KT_ASSERT(integrator.getNumRejectedSteps() == 0);
    checkPosition(platform + " " + method + " step", platform, start, t, positionsOf(*context)[0]);

    context->setPositions({start});
    context->setTime(0.0);
    integrator.setStepSize(h);
    t = 0.7371;  // not a multiple of the step: the last step is shortened
    integrator.stepTo(t);
    KT_ASSERT(context->getState(State::Positions).getTime() == t);
    checkPosition(platform + " " + method + " stepTo", platform, start, t, positionsOf(*context)[0]);
    delete context;
}

} // namespace

int main() {
    return runTest("TestRPYFreeFall: one bead, constant force, v = mu0 F", [] {
        const char* methods[] = {"euler", "heun", "midpoint", "rk23", "rkc2",
                                 "euler_maruyama", "ito_heun", "leimkuhler_matthews"};
        for (const std::string& platform : platformNames(false))
            for (const char* method : methods)
                fall(platform, method);
    });
}
