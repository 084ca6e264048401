// stepToWithin(time, maxSeconds) gives the caller control back between steps, and the steps
// are those of one stepTo(time) call.
//
// RPYIntegrator.h: "after each accepted step, return once maxSeconds of wall-clock time have
// passed since the call (0: after one step; +infinity: as stepTo). Returns true when time is
// reached ... the next call goes on with exactly the steps one stepTo(time) call would have
// taken". knotmm's plugin engine loops on it so that a stretch between two reports answers
// SIGINT/SIGTERM and is checked within a second (issue 30, BUG-13: one stepTo call used to
// hold a blown-up run for minutes). Checks, on a ring of 6 beads with bonds and a downward
// field, for rk23 (adaptive) and ito_heun (Brownian, kT = 0.5), on Reference and CPU:
//   * stepToWithin(0.3, 0) takes exactly one accepted step per call and returns false until
//     the last one, which lands on 0.3 exactly and returns true;
//   * positions, time and counters then equal one stepTo(0.3) bit for bit;
//   * once reached, a further call takes no step and returns true;
//   * stepToWithin(0.6, +inf) equals stepTo(0.6);
//   * maxSeconds < 0 or NaN throws OpenMMException and takes no step.

#include "TestUtilities.h"

#include <limits>
#include <memory>

using namespace OpenMM;
using namespace knotmm_test;

namespace {

System* ring(std::vector<Vec3>& start) {
    const int n = 6;
    System* system = new System();
    HarmonicBondForce* bonds = new HarmonicBondForce();
    CustomExternalForce* gravity = new CustomExternalForce("z");
    for (int i = 0; i < n; i++) {
        system->addParticle(1.0);
        bonds->addBond(i, (i + 1) % n, 0.6, 50.0);
        gravity->addParticle(i, {});
        const double a = 2.0 * 3.14159265358979323846 * i / n;
        start.push_back(Vec3(0.65 * std::cos(a), 0.6 * std::sin(a), 0.15 * std::cos(2 * a)));
    }
    system->addForce(bonds);
    system->addForce(gravity);
    return system;
}

KnotMM::RPYIntegrator* integrator(const std::string& method) {
    KnotMM::RPYIntegrator* integ = new KnotMM::RPYIntegrator(0.005, method, 1e-5);
    if (method == "ito_heun")
        integ->setThermalEnergy(0.5);
    integ->setRandomNumberSeed(4242);
    return integ;
}

void checkMethod(const std::string& platform, const std::string& method) {
    std::vector<Vec3> start;
    std::unique_ptr<System> system(ring(start));
    std::unique_ptr<KnotMM::RPYIntegrator> whole(integrator(method)), parts(integrator(method));
    std::unique_ptr<Context> a(makeContext(*system, *whole, platform));
    std::unique_ptr<Context> b(makeContext(*system, *parts, platform));
    a->setPositions(start);
    b->setPositions(start);
    whole->stepTo(0.3);

    long long calls = 0;
    bool reached = false;
    while (!reached) {
        const long long before = parts->getNumAcceptedSteps();
        reached = parts->stepToWithin(0.3, 0.0);
        calls++;
        KT_ASSERT(parts->getNumAcceptedSteps() == before + 1);
        KT_ASSERT(reached || b->getState(State::Positions).getTime() < 0.3);
        KT_ASSERT(calls < 100000);
    }
    KT_ASSERT(calls == whole->getNumAcceptedSteps() && calls > 5);
    KT_ASSERT(b->getState(State::Positions).getTime() == 0.3);
    const std::vector<Vec3> xa = positionsOf(*a), xb = positionsOf(*b);
    for (size_t i = 0; i < xa.size(); i++)
        KT_ASSERT(xa[i] == xb[i]);
    KT_ASSERT(parts->getNumRejectedSteps() == whole->getNumRejectedSteps());
    KT_ASSERT(parts->getNumForceEvaluations() == whole->getNumForceEvaluations());
    KT_ASSERT(parts->stepToWithin(0.3, 0.0));  // reached: no step
    KT_ASSERT(parts->getNumAcceptedSteps() == calls);

    whole->stepTo(0.6);
    KT_ASSERT(parts->stepToWithin(0.6, std::numeric_limits<double>::infinity()));
    const std::vector<Vec3> ya = positionsOf(*a), yb = positionsOf(*b);
    for (size_t i = 0; i < ya.size(); i++)
        KT_ASSERT(ya[i] == yb[i]);

    const double bad[] = {-1.0, std::numeric_limits<double>::quiet_NaN()};
    for (double budget : bad) {
        KT_EXPECT_THROW("stepToWithin(0.9, bad budget)", [&] { parts->stepToWithin(0.9, budget); });
        KT_ASSERT(parts->getNumAcceptedSteps() == whole->getNumAcceptedSteps());
    }
    std::printf("  %-13s %-9s %lld calls of one step each = one stepTo(0.3), bit for bit\n",
                platform.c_str(), method.c_str(), calls);
}

} // namespace

int main() {
    return runTest("TestRPYStepToWithin: a time budget ends a call between steps, not a step", [] {
        for (const std::string& platform : platformNames())
            for (const char* method : {"rk23", "ito_heun"})
                checkMethod(platform, method);
    });
}
