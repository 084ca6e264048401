// Context checkpoints continue bit for bit.
//
// The reference is the run itself, taken once: from a checkpoint written after some steps,
// the same number of further steps must give bit-identical positions, time, step size and
// counters as the first time. This is what the README promises (checkpoints carry the step
// size, the counters, the PI memories, the cached FSAL velocity, rkc2's spectral radius and
// eigenvector, the noise generator and leimkuhler_matthews's held kick). Any state left out
// shows as a difference: e.g. a noise stream not restored gives other Brownian kicks, a lost
// PI memory or FSAL velocity another step size sequence.
//
// System: a ring of 6 beads, harmonic bonds (l0 = 0.6, k = 50) and a constant downward field
// (gravity), from a bent, non-planar start. Methods: every one: euler, heun, midpoint, rk23,
// rkc2 (deterministic; rk23 at tolerance 1e-5 so the controller is active), euler_maruyama,
// ito_heun, leimkuhler_matthews at kT = 0.5 (Pe = 2, Cholesky noise). 15 steps, checkpoint,
// 25 steps (record), loadCheckpoint, 25 steps (compare); on Reference and on CPU when it loads.

#include "TestUtilities.h"

#include <sstream>

using namespace OpenMM;
using namespace knotmm_test;

namespace {

struct Snapshot {
    std::vector<Vec3> x;
    double time, step;
    long long accepted, rejected, evaluations;
};

Snapshot snap(Context& context, KnotMM::RPYIntegrator& integ) {
    return {positionsOf(context), context.getState(State::Positions).getTime(), integ.getStepSize(),
            integ.getNumAcceptedSteps(), integ.getNumRejectedSteps(), integ.getNumForceEvaluations()};
}

void checkMethod(const std::string& platform, const std::string& method) {
    const int n = 6;
    System system;
    HarmonicBondForce* bonds = new HarmonicBondForce();
    CustomExternalForce* gravity = new CustomExternalForce("z");
    std::vector<Vec3> start;
    for (int i = 0; i < n; i++) {
        system.addParticle(1.0);
        bonds->addBond(i, (i + 1) % n, 0.6, 50.0);
        gravity->addParticle(i, {});
        const double a = 2.0 * 3.14159265358979323846 * i / n;
        start.push_back(Vec3(0.65 * std::cos(a), 0.6 * std::sin(a), 0.15 * std::cos(2 * a)));
    }
    system.addForce(bonds);
    system.addForce(gravity);
    const bool stochastic = method == "euler_maruyama" || method == "ito_heun" || method == "leimkuhler_matthews";
    KnotMM::RPYIntegrator integ(0.005, method, 1e-5);
    if (stochastic)
        integ.setThermalEnergy(0.5);
    integ.setRandomNumberSeed(31337);
    Context* context = makeContext(system, integ, platform);
    context->setPositions(start);
    integ.step(15);
    std::stringstream checkpoint;
    context->createCheckpoint(checkpoint);
    integ.step(25);
    const Snapshot first = snap(*context, integ);
    context->loadCheckpoint(checkpoint);
    integ.step(25);
    const Snapshot second = snap(*context, integ);

    double moved = 0.0;
    for (int i = 0; i < n; i++) {
        KT_ASSERT(first.x[i] == second.x[i]);
        moved = std::max(moved, std::sqrt((first.x[i] - start[i]).dot(first.x[i] - start[i])));
    }
    KT_ASSERT(moved > 1e-3);
    KT_ASSERT(first.time == second.time && first.step == second.step);
    KT_ASSERT(first.accepted == second.accepted && first.rejected == second.rejected);
    KT_ASSERT(first.evaluations == second.evaluations);
    std::printf("  %-13s %-20s bit-identical after the restart (t = %.6g, %lld accepted, %lld rejected)\n",
                platform.c_str(), method.c_str(), second.time, second.accepted, second.rejected);
    delete context;
}

} // namespace

int main() {
    return runTest("TestRPYCheckpoint: createCheckpoint / loadCheckpoint continue bit for bit", [] {
        const char* methods[] = {"euler", "heun", "midpoint", "rk23", "rkc2",
                                 "euler_maruyama", "ito_heun", "leimkuhler_matthews"};
        for (const std::string& platform : platformNames())
            for (const char* method : methods)
                checkMethod(platform, method);
    });
}
