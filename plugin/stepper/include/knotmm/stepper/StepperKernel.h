#ifndef KNOTMM_STEPPER_STEPPER_KERNEL_H_
#define KNOTMM_STEPPER_STEPPER_KERNEL_H_

// IntegrateRPYStepKernel for any platform: a Stepper over the Backend that the platform's
// kernel makes (createBackend). A platform's kernel is this class plus that one function.

#include "knotmm/RPYKernels.h"
#include "knotmm/stepper/Stepper.h"

#include <memory>

namespace KnotMM {

class StepperKernel : public IntegrateRPYStepKernel {
public:
    StepperKernel(std::string name, const OpenMM::Platform& platform)
        : IntegrateRPYStepKernel(name, platform) {}
    void initialize(const OpenMM::System& system, const RPYIntegrator& integrator) override;
    double execute(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double targetTime) override;
    void computeGroupEnergies(OpenMM::ContextImpl& context, const std::vector<int>& groups,
                              std::vector<double>& energies) override;
    void invalidateCache() override;
    void createCheckpoint(std::ostream& stream) const override;
    void loadCheckpoint(std::istream& stream) override;
    long long getNumForceEvaluations() const override { return stepper->counts().evaluations; }
    long long getNumAcceptedSteps() const override { return stepper->counts().accepted; }
    long long getNumRejectedSteps() const override { return stepper->counts().rejected; }
    int getLastStages() const override { return stepper->lastStages(); }
    double getSpectralRadius() const override { return stepper->spectralRadius(); }
    double estimateSpectralRadius(OpenMM::ContextImpl& context, RPYIntegrator& integrator) override {
        return stepper->estimateSpectralRadius(context, integrator);
    }
    RPYCopies* getCopies() const override { return copies.get(); }

protected:
    /** The platform's backend for `system` (checked already: not periodic, no constraints). */
    virtual std::unique_ptr<RPYBackend> createBackend(const OpenMM::System& system,
                                                      const RPYIntegrator& integrator) = 0;
    /**
     * The platform's copies (integrator.getNumCopies() > 1); the default refuses: a platform
     * without them says so when the Context is created.
     */
    virtual std::unique_ptr<RPYCopies> createCopies(const OpenMM::System& system, const RPYIntegrator& integrator);

private:
    const RPYIntegrator* owner = nullptr;  // the integrator initialize() was given
    std::unique_ptr<RPYBackend> backend;
    std::unique_ptr<Stepper> stepper;
    std::unique_ptr<RPYCopies> copies;
};

} // namespace KnotMM

#endif
