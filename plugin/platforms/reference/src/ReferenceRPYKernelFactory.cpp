#include "ReferenceRPYKernels.h"

#include "openmm/KernelFactory.h"
#include "openmm/OpenMMException.h"
#include "openmm/Platform.h"
#include "openmm/internal/ContextImpl.h"

using namespace OpenMM;
using namespace KnotMM;

namespace {

class ReferenceRPYKernelFactory : public KernelFactory {
public:
    KernelImpl* createKernelImpl(std::string name, const Platform& platform, ContextImpl& context) const override {
        if (name == IntegrateRPYStepKernel::Name())
            return new ReferenceIntegrateRPYStepKernel(name, platform);
        throw OpenMMException("ReferenceRPYKernelFactory: no kernel named '" + name + "'");
    }
};

} // namespace

// The plugin does not live in OpenMM's plugin directory, so nothing calls
// registerKernelFactories() at start-up: the Python module calls this at import instead.
// The CPU platform derives from the Reference platform (same PlatformData), so the Reference
// kernel serves both. Registering twice is harmless: a platform that already has the kernel
// is skipped. The XmlSerializer proxy of RPYIntegrator is registered here too.
extern "C" void registerRPYSerializationProxies();

extern "C" void registerRPYKernelFactories() {
    registerRPYSerializationProxies();
    for (const char* name : {"Reference", "CPU"}) {
        for (int i = 0; i < Platform::getNumPlatforms(); i++) {
            Platform& platform = Platform::getPlatform(i);
            if (platform.getName() == name &&
                !platform.supportsKernels({IntegrateRPYStepKernel::Name()}))
                platform.registerKernelFactory(IntegrateRPYStepKernel::Name(), new ReferenceRPYKernelFactory());
        }
    }
}
