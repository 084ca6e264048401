#include "knotmm/stepper/StepperKernel.h"

#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "knotmm/stepper/BinaryIO.h"

using namespace OpenMM;
using namespace KnotMM;

void StepperKernel::initialize(const System& system, const RPYIntegrator& integrator) {
    if (system.usesPeriodicBoundaryConditions())
        throw OpenMMException("RPYIntegrator: the System is periodic, but the RPY mobility here is "
                              "the free-space one (no periodic images); use non-periodic forces");
    if (system.getNumConstraints() > 0)
        throw OpenMMException("RPYIntegrator: the System has constraints, which overdamped RPY "
                              "dynamics does not support; use stiff bonds instead");
    int beads = 0;
    for (int i = 0; i < system.getNumParticles(); i++)
        beads += system.isVirtualSite(i) ? 0 : 1;
    if (beads == 0)
        throw OpenMMException("RPYIntegrator: the System has no particles to move");
    stepper.reset();
    owner = &integrator;
    backend = createBackend(system, integrator);
    stepper.reset(new Stepper(*backend, integrator));
    copies.reset();
    if (integrator.getNumCopies() > 1)
        copies = createCopies(system, integrator);
}

std::unique_ptr<RPYCopies> StepperKernel::createCopies(const System&, const RPYIntegrator&) {
    throw OpenMMException("RPYIntegrator: copies of a system (numCopies > 1) run on the Reference, CPU, OpenCL "
                          "and CUDA platforms; this one (" + getPlatform().getName() + ") has none");
}

double StepperKernel::execute(ContextImpl& context, RPYIntegrator& integrator, double targetTime) {
    return stepper->step(context, integrator, targetTime);
}

void StepperKernel::computeGroupEnergies(ContextImpl& context, const std::vector<int>& groups,
                                         std::vector<double>& energies) {
    stepper->groupEnergies(context, *owner, groups, energies);
}

void StepperKernel::invalidateCache() { stepper->invalidateCache(); }

void StepperKernel::createCheckpoint(std::ostream& stream) const {
    stepper->createCheckpoint(stream);
    if (copies == nullptr)
        return;
    // the copies after the whole system's part: each one's positions, time and state
    for (int k = 0; k < copies->numCopies(); k++) {
        binary::putVector(stream, copies->getPositions(k));
        binary::put(stream, copies->getTime(k));
        copies->createCheckpoint(k, stream);
    }
}

void StepperKernel::loadCheckpoint(std::istream& stream) {
    stepper->loadCheckpoint(stream);
    if (copies == nullptr)
        return;
    for (int k = 0; k < copies->numCopies(); k++) {
        std::vector<double> positions;
        double time = 0.0;
        binary::getVector(stream, positions);
        binary::get(stream, time);
        if (!stream || (int) positions.size() != 3 * copies->beadsPerCopy())
            throw OpenMMException("RPYIntegrator: the checkpoint does not hold this batch's copies");
        copies->setPositions(k, positions);
        copies->setTime(k, time);
        copies->loadCheckpoint(k, stream);
    }
}
