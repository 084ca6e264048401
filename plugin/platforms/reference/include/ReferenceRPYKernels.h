#ifndef KNOTMM_REFERENCE_RPY_KERNELS_H_
#define KNOTMM_REFERENCE_RPY_KERNELS_H_

#include "ReferenceRPYBackend.h"
#include "ReferenceRPYBatch.h"
#include "knotmm/stepper/StepperKernel.h"
#include "openmm/Platform.h"

namespace KnotMM {

/** The integrator's kernel on the Reference and CPU platforms: the stepper over ReferenceRPYBackend. */
class ReferenceIntegrateRPYStepKernel : public StepperKernel {
public:
    ReferenceIntegrateRPYStepKernel(std::string name, const OpenMM::Platform& platform)
        : StepperKernel(name, platform) {}

protected:
    std::unique_ptr<RPYBackend> createBackend(const OpenMM::System& system,
                                              const RPYIntegrator& integrator) override {
        return std::unique_ptr<RPYBackend>(new ReferenceRPYBackend(system, integrator, singleForces()));
    }
    std::unique_ptr<RPYCopies> createCopies(const OpenMM::System& system,
                                            const RPYIntegrator& integrator) override {
        return std::unique_ptr<RPYCopies>(new ReferenceRPYBatch(system, integrator, singleForces()));
    }

private:
    /** The CPU platform computes its forces in single precision, the Reference platform in double. */
    bool singleForces() { return getPlatform().getName() == "CPU"; }
};

} // namespace KnotMM

#endif
