#ifndef KNOTMM_STEPPER_STEPPER_H_
#define KNOTMM_STEPPER_STEPPER_H_

// The platform-independent part of RPYIntegrator: one accepted step of any method (the
// formulas in FixedSteps, RK23Control, RKC2Control, AdaptiveBrownian), landing on target
// times, faults, and the checkpoint layout, over the vector operations and physics of an
// RPYBackend.

#include "knotmm/RPYIntegrator.h"
#include "knotmm/stepper/AdaptiveBrownian.h"
#include "knotmm/stepper/FixedSteps.h"
#include "knotmm/stepper/RK23.h"
#include "knotmm/stepper/RKC2.h"

#include <iosfwd>

namespace KnotMM {

class Stepper {
public:
    /** The method, noise seed and rkc2 start vector come from `integrator`. */
    Stepper(RPYBackend& backend, const RPYIntegrator& integrator);
    /**
     * Take one accepted step, never past targetTime (ps; +infinity for none), and update the
     * Context's positions, time and step count; returns the step taken. On a fault
     * (RPYStepFault, or any other exception) the Context keeps the step's start.
     */
    double step(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double targetTime);
    /**
     * step() for a state whose time is kept outside the Context (a copy of a batch,
     * BatchStepper): one accepted step from time t0 (ps), never past targetTime; the
     * backend's positions are updated, the Context's time and step count are not.
     */
    double advance(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double t0, double targetTime);
    /** Forget cached velocities (the state was changed from outside). */
    void invalidateCache();
    /**
     * The positions the state is kept for (the Context's, or a copy's) may have been set from
     * outside: the next step checks them (a copy's setPositions; a Context signals it through
     * RPYIntegrator::getPositionsVersion).
     */
    void positionsChanged() { checkPositions = true; }
    /** Energies of `groups` at the state (RPYBackend::groupEnergies). */
    void groupEnergies(OpenMM::ContextImpl& context, const RPYIntegrator& integrator, const std::vector<int>& groups,
                       std::vector<double>& energies);
    /** Everything that decides the next steps, so a restored run repeats bit for bit. */
    void createCheckpoint(std::ostream& stream) const;
    void loadCheckpoint(std::istream& stream);
    const StepCounts& counts() const { return work.counts; }
    int lastStages() const { return rkc2.lastStages; }
    double spectralRadius() const { return rkc2.spectralRadiusEstimate(); }
    /** RPYIntegrator::estimateSpectralRadius: a fresh rkc2's estimate, nothing changed. */
    double estimateSpectralRadius(OpenMM::ContextImpl& context, RPYIntegrator& integrator);

private:
    /**
     * work.y = the state the next step starts from: the one the stepper keeps (in double,
     * whatever the platform's precision), unless the positions were set from outside to
     * something else than what it last wrote; then the Context's, and the caches are dropped.
     */
    void syncState(OpenMM::ContextImpl& context, const RPYIntegrator& integrator);
    bool haveState = false;       // work.y holds the state (after a first step or a checkpoint)
    bool checkPositions = false;  // compare the Context's positions with work.y at the next step
    long long seenVersion = 0;    // the integrator's positions version work.y was checked against
    StepWork work;
    FixedSteps fixed;
    RK23Control rk23;
    RKC2Control rkc2;
    AdaptiveBrownian brownian;
};

} // namespace KnotMM

#endif
