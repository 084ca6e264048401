// The stepper keeps its state in double precision whatever the platform's precision, and
// hears of positions set from outside through OpenMM's Integrator::stateChanged (issue 32,
// backend v2). On every platform present (Reference, CPU, OpenCL in double, mixed and single
// precision):
//
//   1. Positions set from outside between steps are honoured: 5 rk23 steps, setPositions(P),
//      one more step equals the first step of a fresh Context at P with the same step size,
//      bit for bit, positions and force evaluations (the velocity cached at the old positions
//      is dropped: 1 + 3 tries evaluations; the try's result does not depend on the
//      controller's memory, only the next step size does). The same through Context.setState,
//      and for positions moved by another integrator of a CompoundIntegrator (no signal).
//   2. Positions read back and set again (what knotmm's engine does between calls) change
//      nothing: 10 steps equal 5 steps, getState, setPositions, 5 steps, bit for bit, with the
//      same number of evaluations (the cached velocity is kept), here for a ring 1e4 d from
//      the origin, where the Context's mixed or single precision positions are much coarser
//      than the state (float spacing at 1e4 d: 1e-3 d).
//   3. A Context checkpoint continues bit for bit in every precision (single included: the
//      checkpoint holds the state in double), again 1e4 d from the origin.
//   4. Mixed and single precision keep the state in double: a ring 1e4 d from the origin moves
//      as the same ring at the origin, within 1e-9 d after 1 tau_d of rk23 (the Context's
//      positions alone would hold it to float spacing, 1e-3 d, or to about 1e-11 relative
//      with mixed precision's correction). Measured on pocl while writing this test: 3e-11 d
//      in mixed precision (5.2e-7 d when the state was read back from the Context each step).

#include "TestSystems.h"
#include "TestUtilities.h"

#include <memory>
#include <sstream>

using namespace OpenMM;
using namespace knotmm_test;

namespace {


// --- 1. positions set from outside ---------------------------------------------------------------

void outsideChangeHonoured(const std::string& platform, bool throughState) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(20, start, 0.0, true));
    Vecs moved = start;
    for (size_t i = 0; i < moved.size(); i++)
        moved[i] = Vec3(start[i][1] + 0.5, -start[i][0], start[i][2] + 0.1 * std::sin(1.0 * i));
    KnotMM::RPYIntegrator integ(0.001, "rk23", 1e-4);
    std::unique_ptr<Context> context(makeContext(*system, integ, platform));
    context->setPositions(start);
    integ.step(5);
    const double h = integ.getStepSize();
    const long long before = integ.getNumForceEvaluations(), triesBefore = integ.getNumAcceptedSteps() + integ.getNumRejectedSteps();
    if (throughState) {
        // a State of another Context holding `moved`: Context.setState sets the positions
        KnotMM::RPYIntegrator other(0.001, "rk23", 1e-4);
        std::unique_ptr<Context> holder(makeContext(*system, other, platform));
        holder->setPositions(moved);
        holder->setTime(context->getState(State::Positions).getTime());
        context->setState(holder->getState(State::Positions | State::Parameters));
    }
    else
        context->setPositions(moved);
    integ.step(1);
    const long long tries = integ.getNumAcceptedSteps() + integ.getNumRejectedSteps() - triesBefore;

    KnotMM::RPYIntegrator fresh(h, "rk23", 1e-4);
    std::unique_ptr<Context> other(makeContext(*system, fresh, platform));
    other->setPositions(moved);
    fresh.step(1);
    std::printf("  %-14s %s after 5 steps: moved %.3g d in the next step (%lld tries)\n", platform.c_str(),
                throughState ? "setState" : "setPositions", maxDeviation(positionsOf(*context), moved), tries);
    KT_ASSERT(positionsOf(*context) == positionsOf(*other));
    KT_ASSERT(integ.getNumForceEvaluations() - before == fresh.getNumForceEvaluations());
    KT_ASSERT(integ.getNumForceEvaluations() - before == 1 + 3 * tries);
}

/**
 * Inside a CompoundIntegrator another integrator moves the positions without OpenMM's
 * stateChanged(): a CustomIntegrator that shifts every bead by (0.3, 0, -0.2) between rk23
 * steps; the next rk23 step equals the first step of a fresh Context at the shifted positions.
 */
void compoundIntegrator(const std::string& platform) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(20, start, 0.0, true));
    CompoundIntegrator compound;
    KnotMM::RPYIntegrator* integ = new KnotMM::RPYIntegrator(0.001, "rk23", 1e-4);
    CustomIntegrator* shift = new CustomIntegrator(0.001);
    shift->addComputePerDof("x", "x + vector(0.3, 0, -0.2)");
    compound.addIntegrator(integ);
    compound.addIntegrator(shift);
    std::unique_ptr<Context> context(makeContext(*system, compound, platform));
    context->setPositions(start);
    compound.setCurrentIntegrator(0);
    integ->step(5);
    const double h = integ->getStepSize();
    compound.setCurrentIntegrator(1);
    shift->step(1);
    const Vecs moved = positionsOf(*context);
    compound.setCurrentIntegrator(0);
    integ->step(1);
    KnotMM::RPYIntegrator fresh(h, "rk23", 1e-4);
    std::unique_ptr<Context> other(makeContext(*system, fresh, platform));
    other->setPositions(moved);
    fresh.step(1);
    std::printf("  %-14s CompoundIntegrator: a shift by another integrator is followed\n", platform.c_str());
    KT_ASSERT(positionsOf(*context) == positionsOf(*other));
}

// --- 2. positions read back and set again ----------------------------------------------------------

struct Run {
    Vecs x;
    double step;
    long long evaluations;
};

Run tenSteps(const std::string& platform, System& system, const Vecs& start, int pause) {
    KnotMM::RPYIntegrator integ(0.001, "rk23", 1e-5);
    std::unique_ptr<Context> context(makeContext(system, integ, platform));
    context->setPositions(start);
    integ.step(pause);
    if (pause < 10) {
        context->setPositions(positionsOf(*context));
        integ.step(10 - pause);
    }
    return {positionsOf(*context), integ.getStepSize(), integ.getNumForceEvaluations()};
}

void setBackChangesNothing(const std::string& platform) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(20, start, 1e4, true));
    const Run plain = tenSteps(platform, *system, start, 10);
    const Run paused = tenSteps(platform, *system, start, 5);
    std::printf("  %-14s 1e4 d away: 10 steps = 5 steps, positions read back and set, 5 steps\n", platform.c_str());
    KT_ASSERT(plain.x == paused.x);
    KT_ASSERT(plain.step == paused.step && plain.evaluations == paused.evaluations);
}

// --- 3. checkpoints ----------------------------------------------------------------------------------

void checkpointBitForBit(const std::string& platform, const std::string& method) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(20, start, 1e4, true));
    KnotMM::RPYIntegrator integ(0.001, method, 1e-5);
    integ.setThermalEnergy(method == "rk23" ? 0.0 : 0.5);
    integ.setRandomNumberSeed(11);
    std::unique_ptr<Context> context(makeContext(*system, integ, platform));
    context->setPositions(start);
    integ.step(5);
    std::stringstream checkpoint;
    context->createCheckpoint(checkpoint);
    integ.step(5);
    const Vecs first = positionsOf(*context);
    const double step = integ.getStepSize();
    context->loadCheckpoint(checkpoint);
    integ.step(5);
    std::printf("  %-14s %-19s checkpoint 1e4 d away: 5 steps again, max difference %.3g d\n", platform.c_str(),
                method.c_str(), maxDeviation(positionsOf(*context), first));
    KT_ASSERT(positionsOf(*context) == first);
    KT_ASSERT(integ.getStepSize() == step);
}

// --- 4. far from the origin ------------------------------------------------------------------------

void farFromOrigin(const std::string& platform) {
    const double offset = 1e4;
    Vecs near, far;
    std::unique_ptr<System> a(ringSystem(20, near, 0.0, true)), b(ringSystem(20, far, offset, true));
    Vecs result[2];
    long long accepted[2];
    for (int which = 0; which < 2; which++) {
        KnotMM::RPYIntegrator integ(0.001, "rk23", 1e-4);
        std::unique_ptr<Context> context(makeContext(which == 0 ? *a : *b, integ, platform));
        context->setPositions(which == 0 ? near : far);
        integ.stepTo(1.0);
        result[which] = positionsOf(*context);
        accepted[which] = integ.getNumAcceptedSteps();
    }
    // what is compared is read back from the Context: rounded to its precision 1e4 d away
    const double readBack = platform.find("single") != std::string::npos ? 1e-3 : 0.0;
    const double deviation = maxDeviation(result[1], result[0], Vec3(offset, -offset, offset));
    std::printf("  %-14s chain of 20 at the origin / 1e4 d away: %lld / %lld accepted steps\n", platform.c_str(),
                accepted[0], accepted[1]);
    KT_CHECK_ABS(platform + ": chain 1e4 d away against the same at the origin (t = 1)", 0.0, deviation,
                 readBack + 1e-9);
    KT_ASSERT(accepted[0] == accepted[1]);
}

} // namespace

int main() {
    return runTest("TestRPYOutsideChanges: the state in double, changes from outside by signal", [] {
        std::vector<std::string> platforms = platformNames();
        if (openclSkipReason().empty())
            platforms.push_back("OpenCL:single");
        else
            std::printf("  OpenCL skipped: %s\n", openclSkipReason().c_str());
        for (const std::string& platform : platforms) {
            outsideChangeHonoured(platform, false);
            outsideChangeHonoured(platform, true);
            compoundIntegrator(platform);
            setBackChangesNothing(platform);
            for (const char* method : {"rk23", "leimkuhler_matthews"})
                checkpointBitForBit(platform, method);
            if (isDevice(platform))
                farFromOrigin(platform);
        }
    });
}
