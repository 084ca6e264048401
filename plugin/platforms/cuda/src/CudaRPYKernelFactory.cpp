// The RPY integrator's kernel on OpenMM's CUDA platform: the device backend of
// plugin/platforms/common over the platform's ComputeContext. Built into its own library,
// libKnotMMRPYPluginCUDA.so, which knotmm.plugin loads with Platform.loadPluginLibrary when
// OpenMM has the CUDA platform (OpenMM then calls registerKernelFactories()).

#include "CommonRPYBackend.h"
#include "knotmm/RPYKernels.h"
#include "openmm/KernelFactory.h"
#include "openmm/OpenMMException.h"
#include "openmm/Platform.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/cuda/CudaContext.h"
#include "openmm/cuda/CudaPlatform.h"

using namespace OpenMM;
using namespace KnotMM;

namespace {

class CudaRPYKernelFactory : public KernelFactory {
public:
    KernelImpl* createKernelImpl(std::string name, const Platform& platform, ContextImpl& context) const override {
        if (name != IntegrateRPYStepKernel::Name())
            throw OpenMMException("CudaRPYKernelFactory: no kernel named '" + name + "'");
        CudaPlatform::PlatformData& data = *static_cast<CudaPlatform::PlatformData*>(context.getPlatformData());
        return new CommonIntegrateRPYStepKernel(name, platform, *data.contexts[0]);
    }
};

/** Registers the kernel for the CUDA platform, if OpenMM has it and it has no such kernel yet. */
void registerFactory() {
    for (int i = 0; i < Platform::getNumPlatforms(); i++) {
        Platform& platform = Platform::getPlatform(i);
        if (platform.getName() == "CUDA" && !platform.supportsKernels({IntegrateRPYStepKernel::Name()}))
            platform.registerKernelFactory(IntegrateRPYStepKernel::Name(), new CudaRPYKernelFactory());
    }
}

} // namespace

// Called by OpenMM's Platform::loadPluginLibrary (registerPlatforms first: nothing to do).
extern "C" void registerPlatforms() {}

extern "C" void registerKernelFactories() { registerFactory(); }

/** The same, under a name of its own (for callers that load the library with ctypes). */
extern "C" void registerRPYCUDAKernelFactories() { registerFactory(); }
