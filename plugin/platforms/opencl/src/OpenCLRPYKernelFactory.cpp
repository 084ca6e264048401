// The RPY integrator's kernel on OpenMM's OpenCL platform: the device backend of
// plugin/platforms/common over the platform's ComputeContext. Built into its own library,
// libKnotMMRPYPluginOpenCL.so, which knotmm.plugin loads with Platform.loadPluginLibrary when
// OpenMM has the OpenCL platform (OpenMM then calls registerKernelFactories()).

#include "CommonRPYBackend.h"
#include "knotmm/RPYKernels.h"
#include "openmm/KernelFactory.h"
#include "openmm/OpenMMException.h"
#include "openmm/Platform.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/opencl/OpenCLContext.h"
#include "openmm/opencl/OpenCLPlatform.h"

using namespace OpenMM;
using namespace KnotMM;

namespace {

class OpenCLRPYKernelFactory : public KernelFactory {
public:
    KernelImpl* createKernelImpl(std::string name, const Platform& platform, ContextImpl& context) const override {
        if (name != IntegrateRPYStepKernel::Name())
            throw OpenMMException("OpenCLRPYKernelFactory: no kernel named '" + name + "'");
        OpenCLPlatform::PlatformData& data = *static_cast<OpenCLPlatform::PlatformData*>(context.getPlatformData());
        return new CommonIntegrateRPYStepKernel(name, platform, *data.contexts[0]);
    }
};

/** Registers the kernel for the OpenCL platform, if OpenMM has it and it has no such kernel yet. */
void registerFactory() {
    for (int i = 0; i < Platform::getNumPlatforms(); i++) {
        Platform& platform = Platform::getPlatform(i);
        if (platform.getName() == "OpenCL" && !platform.supportsKernels({IntegrateRPYStepKernel::Name()}))
            platform.registerKernelFactory(IntegrateRPYStepKernel::Name(), new OpenCLRPYKernelFactory());
    }
}

} // namespace

// Called by OpenMM's Platform::loadPluginLibrary (registerPlatforms first: nothing to do).
extern "C" void registerPlatforms() {}

extern "C" void registerKernelFactories() { registerFactory(); }

/** The same, under a name of its own (for callers that load the library with ctypes). */
extern "C" void registerRPYOpenCLKernelFactories() { registerFactory(); }
