// stepTo with a time that cannot be reached raises; one within the landing slack is reached.
//
// RPYIntegrator.h documents stepTo(time): "Advance to `time` (ps) exactly ... a time within
// landingSlack(time) counts as reached. A time that is not finite, or earlier than the
// Context's by more than the slack, throws OpenMMException." (plugin/README.md: the slack is
// 1e-9 relative, knotmm's landing rule.) Checks, from a Context at t = 0.5 ps:
//   * stepTo(NaN), stepTo(+inf), stepTo(0.25): OpenMMException, and positions, time and step
//     count are left as they were;
//   * stepTo(0.5 - 1e-12), inside the slack: no exception and no step (already reached);
//   * stepTo(0.75) afterwards still works and lands exactly (the Context is usable).
// (The plugin before the refactor that introduced this contract returned silently from
// stepTo(NaN) and from an earlier time: `while (time < target - slack)` is false for both.)

#include "TestUtilities.h"

#include <limits>

using namespace OpenMM;
using namespace knotmm_test;

int main() {
    return runTest("TestRPYStepToInvalid: stepTo(NaN / inf / an earlier time) raises", [] {
        setUpPlatforms();
        System system;
        system.addParticle(1.0);
        CustomExternalForce* field = new CustomExternalForce("z");
        field->addParticle(0, {});
        system.addForce(field);
        KnotMM::RPYIntegrator integ(0.01, "rk23");
        Context context(system, integ, Platform::getPlatformByName("Reference"));
        context.setPositions({Vec3(0, 0, 0)});
        integ.stepTo(0.5);
        const Vec3 before = positionsOf(context)[0];
        const long long steps = integ.getNumAcceptedSteps();
        const struct {
            const char* name;
            double time;
        } bad[] = {{"stepTo(NaN)", std::numeric_limits<double>::quiet_NaN()},
                   {"stepTo(+inf)", std::numeric_limits<double>::infinity()},
                   {"stepTo(0.25) from t = 0.5", 0.25}};
        for (const auto& b : bad) {
            KT_EXPECT_THROW(b.name, [&] { integ.stepTo(b.time); });
            KT_ASSERT(positionsOf(context)[0] == before);
            KT_ASSERT(context.getState(State::Positions).getTime() == 0.5);
            KT_ASSERT(integ.getNumAcceptedSteps() == steps);
        }
        integ.stepTo(0.5 - 1e-12);  // within the slack: reached already, nothing happens
        KT_ASSERT(positionsOf(context)[0] == before);
        KT_ASSERT(integ.getNumAcceptedSteps() == steps);
        integ.stepTo(0.75);
        KT_ASSERT(context.getState(State::Positions).getTime() == 0.75);
        KT_CHECK_ABS("z after stepTo(0.75) (v = -1)", -0.75, positionsOf(context)[0][2], 1e-12);
    });
}
