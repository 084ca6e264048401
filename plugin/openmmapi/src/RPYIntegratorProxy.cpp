// XmlSerializer support: RPYIntegrator's settings (not its run state: that is what
// Context.createCheckpoint is for) to and from XML.

#include "knotmm/RPYIntegrator.h"

#include "openmm/OpenMMException.h"
#include "openmm/serialization/SerializationNode.h"
#include "openmm/serialization/SerializationProxy.h"

#include <typeinfo>

using namespace OpenMM;
using namespace KnotMM;

namespace {

class RPYIntegratorProxy : public SerializationProxy {
public:
    RPYIntegratorProxy() : SerializationProxy("KnotMMRPYIntegrator") {}

    void serialize(const void* object, SerializationNode& node) const override {
        const RPYIntegrator& integ = *reinterpret_cast<const RPYIntegrator*>(object);
        node.setIntProperty("version", 1);
        node.setStringProperty("method", integ.getMethod());
        node.setDoubleProperty("stepSize", integ.getStepSize());
        node.setDoubleProperty("errorTolerance", integ.getErrorTolerance());
        node.setDoubleProperty("beadDiameter", integ.getBeadDiameter());
        node.setDoubleProperty("mobility", integ.getMobility());
        node.setDoubleProperty("thermalEnergy", integ.getThermalEnergy());
        node.setIntProperty("randomSeed", integ.getRandomNumberSeed());
        node.setDoubleProperty("minimumStepSize", integ.getMinimumStepSize());
        node.setDoubleProperty("maximumStepSize", integ.getMaximumStepSize());
        node.setIntProperty("numThreads", integ.getNumThreads());
        node.setStringProperty("noiseMethod", integ.getNoiseMethod());
        node.setStringProperty("noisePrecision", integ.getNoisePrecision());
        node.setDoubleProperty("lanczosTolerance", integ.getLanczosTolerance());
        node.setIntProperty("integrationForceGroups", integ.getIntegrationForceGroups());
        SerializationNode& start = node.createChildNode("SpectralRadiusStartVector");
        for (const Vec3& v : integ.getSpectralRadiusStartVector())
            start.createChildNode("Vector").setDoubleProperty("x", v[0]).setDoubleProperty("y", v[1]).setDoubleProperty("z", v[2]);
    }

    void* deserialize(const SerializationNode& node) const override {
        if (node.getIntProperty("version") != 1)
            throw OpenMMException("RPYIntegrator: unsupported XML version");
        RPYIntegrator* integ = new RPYIntegrator(node.getDoubleProperty("stepSize"),
                                                 node.getStringProperty("method"),
                                                 node.getDoubleProperty("errorTolerance"));
        try {
            integ->setBeadDiameter(node.getDoubleProperty("beadDiameter"));
            integ->setMobility(node.getDoubleProperty("mobility"));
            integ->setThermalEnergy(node.getDoubleProperty("thermalEnergy"));
            integ->setRandomNumberSeed(node.getIntProperty("randomSeed"));
            integ->setMinimumStepSize(node.getDoubleProperty("minimumStepSize"));
            integ->setMaximumStepSize(node.getDoubleProperty("maximumStepSize"));
            integ->setNumThreads(node.getIntProperty("numThreads"));
            integ->setNoiseMethod(node.getStringProperty("noiseMethod", "cholesky"));
            integ->setNoisePrecision(node.getStringProperty("noisePrecision", "auto"));
            integ->setLanczosTolerance(node.getDoubleProperty("lanczosTolerance", 1e-6));
            integ->setIntegrationForceGroups(node.getIntProperty("integrationForceGroups"));
            std::vector<Vec3> start;
            for (const SerializationNode& child : node.getChildNode("SpectralRadiusStartVector").getChildren())
                start.push_back(Vec3(child.getDoubleProperty("x"), child.getDoubleProperty("y"), child.getDoubleProperty("z")));
            integ->setSpectralRadiusStartVector(start);
        }
        catch (...) {
            delete integ;
            throw;
        }
        return integ;
    }
};

} // namespace

extern "C" void registerRPYSerializationProxies() {
    static bool done = false;
    if (!done) {
        SerializationProxy::registerProxy(typeid(RPYIntegrator), new RPYIntegratorProxy());
        done = true;
    }
}
