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

/**
 * K copies of one system in one Context, each with its own state, time and steps
 * (RPYIntegrator::setNumCopies): what a platform that supports them implements. Copy k's
 * beads are the System's beads k n .. (k + 1) n - 1 (virtual sites are not beads); the copies
 * see each other in no force (they are kept apart in space) and the mobility is block
 * diagonal. Positions are 3n numbers, bead-major, in nm (= d); times in ps (= tau_d).
 */
class RPYCopies {
public:
    virtual ~RPYCopies() {}
    virtual int numCopies() const = 0;
    virtual int beadsPerCopy() const = 0;
    /**
     * Step every copy that has not failed towards targets[k] (ps), each with its own step
     * control, landing exactly, all copies' forces in one evaluation of the Context; returns
     * once every copy has reached its target or failed, or, after a step, once maxSeconds of
     * wall-clock time are spent (true: every copy that has not failed is at its target). A
     * copy's failed step records its fault (copyFault) and leaves it at its last good state.
     */
    virtual bool stepTo(OpenMM::ContextImpl& context, RPYIntegrator& integrator,
                        const std::vector<double>& targets, double maxSeconds) = 0;
    virtual std::vector<double> getPositions(int copy) const = 0;
    virtual void setPositions(int copy, const std::vector<double>& positions) = 0;
    virtual double getTime(int copy) const = 0;
    virtual void setTime(int copy, double time) = 0;
    /** The copy's integrator state in RPYIntegrator's checkpoint layout (step size, stepper). */
    virtual void createCheckpoint(int copy, std::ostream& stream) const = 0;
    virtual void loadCheckpoint(int copy, std::istream& stream) = 0;
    /** The copy's fault: its kind (RPYStepFault::kindName, "error" for another) and message; "" for none. */
    virtual std::string faultKind(int copy) const = 0;
    virtual std::string faultMessage(int copy) const = 0;
    virtual void clearFault(int copy) = 0;
    /** Centre-to-centre distance of neighbouring copies in the Context (nm). */
    virtual double spacing() const = 0;
};

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
    /** The copies of a batch (RPYIntegrator::getNumCopies() > 1), nullptr for one system. */
    virtual RPYCopies* getCopies() const { return nullptr; }
};

} // namespace KnotMM

#endif
