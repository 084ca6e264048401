// XmlSerializer round trip of RPYIntegrator's settings.
//
// XmlSerializer::serialize<Integrator> writes the integrator through its registered proxy
// (type "KnotMMRPYIntegrator", registered by registerRPYKernelFactories()) and
// deserialize<Integrator> must give back an RPYIntegrator (dynamic_cast succeeds) whose every
// setting equals the one set here: method, step size, error tolerance, thermal energy, seed,
// noise method, Lanczos tolerance, minimum and maximum step, threads, bead diameter, mobility,
// integration force groups and rkc2's start vector. The expected values are the literals
// below, all different from the defaults (checked first, so the round trip cannot pass by
// falling back to a default). Doubles are compared exactly: the values are chosen with short
// decimal forms and OpenMM writes doubles with enough digits to read them back unchanged.
//
// A second check runs a Context with the original and with the deserialised integrator from
// the same positions (seeded Brownian method, so the noise stream depends on the seed read
// back): the trajectories are bit-identical, i.e. the settings that drive the steps came back.

#include "TestUtilities.h"
#include "openmm/serialization/XmlSerializer.h"

#include <memory>
#include <sstream>

using namespace OpenMM;
using namespace knotmm_test;

namespace {

void configure(KnotMM::RPYIntegrator& integ) {
    integ.setThermalEnergy(0.35);
    integ.setRandomNumberSeed(918273);
    integ.setNoiseMethod("lanczos");
    integ.setLanczosTolerance(2.5e-7);
    integ.setMinimumStepSize(3e-6);
    integ.setMaximumStepSize(0.25);
    integ.setNumThreads(3);
    integ.setBeadDiameter(1.25);
    integ.setMobility(0.75);
    integ.setErrorTolerance(4e-5);
    integ.setIntegrationForceGroups(0x5);
    integ.setSpectralRadiusStartVector({Vec3(0.1, -0.2, 0.3), Vec3(-1.5, 2.0, 0.25)});
}

std::unique_ptr<KnotMM::RPYIntegrator> roundTrip(const KnotMM::RPYIntegrator& original, std::string& xml) {
    std::stringstream buffer;
    XmlSerializer::serialize<Integrator>(&original, "Integrator", buffer);
    xml = buffer.str();
    Integrator* copy = XmlSerializer::deserialize<Integrator>(buffer);
    KnotMM::RPYIntegrator* rpy = dynamic_cast<KnotMM::RPYIntegrator*>(copy);
    if (rpy == nullptr) {
        delete copy;
        throw Failure("deserialize<Integrator> did not give an RPYIntegrator");
    }
    return std::unique_ptr<KnotMM::RPYIntegrator>(rpy);
}

void checkSettings() {
    KnotMM::RPYIntegrator defaults(0.01);
    KnotMM::RPYIntegrator original(0.0125, "leimkuhler_matthews", 1e-4);
    configure(original);
    // every setting differs from its default, so a dropped one cannot round-trip by accident
    KT_ASSERT(defaults.getMethod() != original.getMethod());
    KT_ASSERT(defaults.getStepSize() != original.getStepSize());
    KT_ASSERT(defaults.getErrorTolerance() != original.getErrorTolerance());
    KT_ASSERT(defaults.getThermalEnergy() != original.getThermalEnergy());
    KT_ASSERT(defaults.getRandomNumberSeed() != original.getRandomNumberSeed());
    KT_ASSERT(defaults.getNoiseMethod() != original.getNoiseMethod());
    KT_ASSERT(defaults.getLanczosTolerance() != original.getLanczosTolerance());
    KT_ASSERT(defaults.getMinimumStepSize() != original.getMinimumStepSize());
    KT_ASSERT(defaults.getMaximumStepSize() != original.getMaximumStepSize());
    KT_ASSERT(defaults.getNumThreads() != original.getNumThreads());
    KT_ASSERT(defaults.getBeadDiameter() != original.getBeadDiameter());
    KT_ASSERT(defaults.getMobility() != original.getMobility());
    KT_ASSERT(defaults.getIntegrationForceGroups() != original.getIntegrationForceGroups());
    KT_ASSERT(defaults.getSpectralRadiusStartVector().empty());

    std::string xml;
    std::unique_ptr<KnotMM::RPYIntegrator> copy = roundTrip(original, xml);
    std::printf("  serialised:\n%s", xml.c_str());
    KT_ASSERT(copy->getMethod() == "leimkuhler_matthews");
    KT_ASSERT(copy->getStepSize() == 0.0125);
    KT_ASSERT(copy->getErrorTolerance() == 4e-5);
    KT_ASSERT(copy->getThermalEnergy() == 0.35);
    KT_ASSERT(copy->getRandomNumberSeed() == 918273);
    KT_ASSERT(copy->getNoiseMethod() == "lanczos");
    KT_ASSERT(copy->getLanczosTolerance() == 2.5e-7);
    KT_ASSERT(copy->getMinimumStepSize() == 3e-6);
    KT_ASSERT(copy->getMaximumStepSize() == 0.25);
    KT_ASSERT(copy->getNumThreads() == 3);
    KT_ASSERT(copy->getBeadDiameter() == 1.25);
    KT_ASSERT(copy->getMobility() == 0.75);
    KT_ASSERT(copy->getIntegrationForceGroups() == 0x5);
    const std::vector<Vec3>& start = copy->getSpectralRadiusStartVector();
    KT_ASSERT(start.size() == 2);
    KT_ASSERT(start[0] == Vec3(0.1, -0.2, 0.3));
    KT_ASSERT(start[1] == Vec3(-1.5, 2.0, 0.25));
    KT_ASSERT(copy->isStochastic() && !copy->isAdaptive());
    std::printf("  all settings round-trip exactly\n");

    // An adaptive method round-trips too (and a kT = 0 one with default noise settings).
    KnotMM::RPYIntegrator rk(0.02, "rkc2", 3e-6);
    rk.setMaximumStepSize(0.5);
    std::unique_ptr<KnotMM::RPYIntegrator> rkCopy = roundTrip(rk, xml);
    KT_ASSERT(rkCopy->getMethod() == "rkc2" && rkCopy->isAdaptive());
    KT_ASSERT(rkCopy->getStepSize() == 0.02 && rkCopy->getErrorTolerance() == 3e-6);
    KT_ASSERT(rkCopy->getMaximumStepSize() == 0.5 && rkCopy->getThermalEnergy() == 0.0);
    KT_ASSERT(rkCopy->getNoiseMethod() == "cholesky" && rkCopy->getLanczosTolerance() == 1e-6);
}

void checkSameTrajectory() {
    // Brownian ring of 4 beads; Cholesky noise (Lanczos needs LAPACK's dstev, which only the
    // Python module hands over).
    System system;
    HarmonicBondForce* bonds = new HarmonicBondForce();
    for (int i = 0; i < 4; i++) {
        system.addParticle(1.0);
        bonds->addBond(i, (i + 1) % 4, 0.8, 30.0);
    }
    system.addForce(bonds);
    const std::vector<Vec3> start = {Vec3(0, 0, 0), Vec3(0.8, 0, 0.1), Vec3(0.8, 0.8, 0), Vec3(0, 0.8, -0.1)};
    KnotMM::RPYIntegrator original(0.002, "ito_heun");
    original.setThermalEnergy(0.5);
    original.setRandomNumberSeed(4242);
    original.setBeadDiameter(1.1);
    original.setMobility(0.9);
    std::string xml;
    std::unique_ptr<KnotMM::RPYIntegrator> copy = roundTrip(original, xml);
    std::vector<Vec3> x[2];
    KnotMM::RPYIntegrator* integrators[2] = {&original, copy.get()};
    for (int run = 0; run < 2; run++) {
        Context* context = makeContext(system, *integrators[run], "Reference");
        context->setPositions(start);
        integrators[run]->step(200);
        x[run] = positionsOf(*context);
        delete context;
    }
    double moved = 0.0;
    for (int i = 0; i < 4; i++) {
        KT_ASSERT(x[0][i] == x[1][i]);
        moved = std::max(moved, std::sqrt((x[0][i] - start[i]).dot(x[0][i] - start[i])));
    }
    KT_ASSERT(moved > 0.05);  // the noise did act
    std::printf("  original and deserialised integrator: bit-identical 200-step trajectories\n");
}

} // namespace

int main() {
    return runTest("TestRPYSerialization: XmlSerializer round trip of RPYIntegrator", [] {
        setUpPlatforms();  // registers the serialization proxy with the kernels
        checkSettings();
        checkSameTrajectory();
    });
}
