// Documented errors: bad settings and failed steps raise OpenMM::OpenMMException, and a failed
// step keeps the last good state.
//
// What is expected comes from the API documentation (RPYIntegrator.h, plugin/README.md):
//   * an unknown method name, a step size / error tolerance that is not a finite number > 0;
//   * thermalEnergy > 0 with a deterministic method, thermalEnergy < 0 or NaN;
//   * unknown noise method; threads < 1;
//   * the seed, bead diameter and mobility are set "before the Context exists";
//   * constraints and periodic Systems are refused (free-space RPY, no constraints);
//   * getGroupEnergies with a group outside 0..31;
//   * rk23 whose step falls below minimumStepSize raises, and the positions before the step
//     are put back (README: "below the minimum a step raises ... and the last good state is
//     kept"), with no time advanced;
//   * Lanczos noise without LAPACK's dstev (which only the Python module hands over) is
//     refused with an OpenMMException, and the state is kept.
// stepTo(NaN / inf / an earlier time) is checked in TestRPYStepToInvalid.cpp.

#include "TestUtilities.h"

#include <limits>

using namespace OpenMM;
using namespace knotmm_test;

namespace {

System* dimerSystem(double k) {
    System* system = new System();
    system->addParticle(1.0);
    system->addParticle(1.0);
    HarmonicBondForce* bond = new HarmonicBondForce();
    bond->addBond(0, 1, 0.6, k);
    system->addForce(bond);
    return system;
}

const std::vector<Vec3> DIMER = {Vec3(0, 0, 0), Vec3(1.4, 0.2, 0.0)};

} // namespace

int main() {
    return runTest("TestRPYErrors: documented errors raise OpenMMException", [] {
        setUpPlatforms();
        const double nan = std::numeric_limits<double>::quiet_NaN();

        // constructor and setters
        KT_EXPECT_THROW("unknown method 'verlet'", [] { KnotMM::RPYIntegrator integ(0.01, "verlet"); });
        KT_EXPECT_THROW("step size 0", [] { KnotMM::RPYIntegrator integ(0.0, "euler"); });
        KT_EXPECT_THROW("step size NaN", [nan] { KnotMM::RPYIntegrator integ(nan, "euler"); });
        KT_EXPECT_THROW("error tolerance -1", [] { KnotMM::RPYIntegrator integ(0.01, "rk23", -1.0); });
        for (const char* method : {"euler", "heun", "midpoint", "rk23", "rkc2"}) {
            KnotMM::RPYIntegrator integ(0.01, method);
            KT_EXPECT_THROW(std::string("kT = 1 with ") + method, [&] { integ.setThermalEnergy(1.0); });
            KT_ASSERT(integ.getThermalEnergy() == 0.0);
            integ.setThermalEnergy(0.0);  // kT = 0 is fine for every method
        }
        {
            KnotMM::RPYIntegrator integ(0.01, "ito_heun");
            KT_EXPECT_THROW("kT = -1", [&] { integ.setThermalEnergy(-1.0); });
            KT_EXPECT_THROW("kT = NaN", [&] { integ.setThermalEnergy(nan); });
            KT_EXPECT_THROW("noise method 'sobol'", [&] { integ.setNoiseMethod("sobol"); });
            KT_EXPECT_THROW("0 threads", [&] { integ.setNumThreads(0); });
            KT_EXPECT_THROW("bead diameter -1", [&] { integ.setBeadDiameter(-1.0); });
            KT_EXPECT_THROW("minimum step 0", [&] { integ.setMinimumStepSize(0.0); });
            KT_ASSERT(integ.getThermalEnergy() == 0.0 && integ.getNoiseMethod() == "cholesky");
        }

        // settings fixed once bound
        {
            System* system = dimerSystem(10.0);
            KnotMM::RPYIntegrator integ(0.01, "leimkuhler_matthews");
            Context context(*system, integ, Platform::getPlatformByName("Reference"));
            KT_EXPECT_THROW("seed after the Context exists", [&] { integ.setRandomNumberSeed(3); });
            KT_EXPECT_THROW("bead diameter after the Context exists", [&] { integ.setBeadDiameter(2.0); });
            KT_EXPECT_THROW("mobility after the Context exists", [&] { integ.setMobility(2.0); });
            context.setPositions(DIMER);
            KT_EXPECT_THROW("getGroupEnergies({32})", [&] { integ.getGroupEnergies({32}); });
            KT_EXPECT_THROW("getGroupEnergies({-1})", [&] { integ.getGroupEnergies({-1}); });
            delete system;
        }

        // Systems the RPY dynamics refuses
        {
            System* system = dimerSystem(10.0);
            system->addConstraint(0, 1, 1.0);
            KnotMM::RPYIntegrator integ(0.01, "euler");
            KT_EXPECT_THROW("System with a constraint", [&] {
                Context context(*system, integ, Platform::getPlatformByName("Reference"));
            });
            delete system;
        }
        {
            System* system = dimerSystem(10.0);
            system->setDefaultPeriodicBoxVectors(Vec3(5, 0, 0), Vec3(0, 5, 0), Vec3(0, 0, 5));
            NonbondedForce* nb = new NonbondedForce();
            nb->setNonbondedMethod(NonbondedForce::CutoffPeriodic);
            nb->setCutoffDistance(2.0);
            nb->addParticle(0.0, 0.5, 0.0);
            nb->addParticle(0.0, 0.5, 0.0);
            system->addForce(nb);
            KnotMM::RPYIntegrator integ(0.01, "euler");
            KT_EXPECT_THROW("periodic System", [&] {
                Context context(*system, integ, Platform::getPlatformByName("Reference"));
            });
            delete system;
        }

        // rk23 below its minimum step: raises, the last good state is kept
        {
            System* system = dimerSystem(1e4);  // stiff: lambda ~ 1e4 / ps
            KnotMM::RPYIntegrator integ(0.5, "rk23", 1e-9);
            integ.setMinimumStepSize(0.01);
            Context context(*system, integ, Platform::getPlatformByName("Reference"));
            context.setPositions(DIMER);
            KT_EXPECT_THROW("rk23 step below minimumStepSize", [&] { integ.step(1); });
            const std::vector<Vec3> x = positionsOf(context);
            KT_ASSERT(x[0] == DIMER[0] && x[1] == DIMER[1]);
            KT_ASSERT(context.getState(State::Positions).getTime() == 0.0);
            KT_ASSERT(context.getState(State::Positions).getStepCount() == 0);
            KT_ASSERT(integ.getNumAcceptedSteps() == 0 && integ.getNumRejectedSteps() > 0);
            std::printf("  positions, time and step count kept after %lld rejected tries\n",
                        integ.getNumRejectedSteps());
            delete system;
        }

        // Lanczos noise from C++ (no dstev handed over): refused (at the step, or already when
        // the Context is made: the documentation does not say when), the state kept
        {
            System* system = dimerSystem(10.0);
            KnotMM::RPYIntegrator integ(0.01, "euler_maruyama");
            integ.setThermalEnergy(1.0);
            integ.setNoiseMethod("lanczos");
            Context* context = nullptr;
            KT_EXPECT_THROW("Lanczos noise without dstev", [&] {
                context = new Context(*system, integ, Platform::getPlatformByName("Reference"));
                context->setPositions(DIMER);
                integ.step(1);
            });
            if (context != nullptr) {
                const std::vector<Vec3> x = positionsOf(*context);
                KT_ASSERT(x[0] == DIMER[0] && x[1] == DIMER[1]);
                KT_ASSERT(context->getState(State::Positions).getTime() == 0.0);
                // back to Cholesky (a setting read at every step): the run goes on
                integ.setNoiseMethod("cholesky");
                integ.step(3);
                KT_ASSERT(integ.getNumAcceptedSteps() == 3);
                delete context;
            }
            delete system;
        }
    });
}
