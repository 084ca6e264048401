#include "knotmm/stepper/StepperKernel.h"

#include "openmm/OpenMMException.h"
#include "openmm/System.h"

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
    backend = createBackend(system, integrator);
    stepper.reset(new Stepper(*backend, integrator));
}

double StepperKernel::execute(ContextImpl& context, RPYIntegrator& integrator, double targetTime) {
    return stepper->step(context, integrator, targetTime);
}

void StepperKernel::computeGroupEnergies(ContextImpl& context, const std::vector<int>& groups,
                                         std::vector<double>& energies) {
    backend->groupEnergies(context, groups, energies);
}

void StepperKernel::invalidateCache() { stepper->invalidateCache(); }

void StepperKernel::createCheckpoint(std::ostream& stream) const { stepper->createCheckpoint(stream); }

void StepperKernel::loadCheckpoint(std::istream& stream) { stepper->loadCheckpoint(stream); }
