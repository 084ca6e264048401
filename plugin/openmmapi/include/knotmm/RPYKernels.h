#ifndef KNOTMM_RPY_KERNELS_H_
#define KNOTMM_RPY_KERNELS_H_

// Abstract kernel of RPYIntegrator. Each platform that supports the integrator registers a
// KernelFactory creating its implementation under IntegrateRPYStepKernel::Name(); the
// Reference implementation (platforms/reference) also serves the CPU platform. A CUDA or
// OpenCL version would live in platforms/<name>/ and derive from this class.

#include "knotmm/RPYIntegrator.h"
#include "openmm/KernelImpl.h"
#include "openmm/System.h"

#include <iosfwd>
#include <string>
#include <vector>

namespace OpenMM {
class ContextImpl;
}

namespace KnotMM {

class IntegrateRPYStepKernel : public OpenMM::KernelImpl {
public:
    static std::string Name() { return "IntegrateRPYStep"; }
    IntegrateRPYStepKernel(std::string name, const OpenMM::Platform& platform)
        : OpenMM::KernelImpl(name, platform) {}
    /** Called once, when the Context is created. */
    virtual void initialize(const OpenMM::System& system, const RPYIntegrator& integrator) = 0;
    /**
     * Take one accepted step, never past targetTime (ps; +infinity for none), and update the
     * context's positions, time and step count. Returns the step taken.
     */
    virtual double execute(OpenMM::ContextImpl& context, RPYIntegrator& integrator,
                           double targetTime) = 0;
    /**
     * Energy of each force group in `groups` at the context's positions shifted to the beads'
     * centre of mass (kJ/mol), into `energies`. Leaves the context's positions and forces and
     * every part of the kernel's state as they were.
     */
    virtual void computeGroupEnergies(OpenMM::ContextImpl& context, const std::vector<int>& groups,
                                      std::vector<double>& energies) = 0;
    /** Drop cached velocities (the state was changed by something other than the kernel). */
    virtual void invalidateCache() = 0;
    virtual void createCheckpoint(std::ostream& stream) const = 0;
    virtual void loadCheckpoint(std::istream& stream) = 0;
    virtual long long getNumForceEvaluations() const = 0;
    virtual long long getNumAcceptedSteps() const = 0;
    virtual long long getNumRejectedSteps() const = 0;
    virtual int getLastStages() const = 0;
    virtual double getSpectralRadius() const = 0;
    /**
     * The spectral radius of the velocity's Jacobian at the context's positions (1/ps), by
     * rkc2's power iteration from its start vector, as a fresh rkc2 would make it before its
     * first step. Leaves the context's positions, the counters and every part of the
     * kernel's state as they were.
     */
    virtual double estimateSpectralRadius(OpenMM::ContextImpl& context, RPYIntegrator& integrator) = 0;
};

} // namespace KnotMM

#endif
