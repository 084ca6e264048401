#ifndef KNOTMM_STEPPER_FIXED_STEPS_H_
#define KNOTMM_STEPPER_FIXED_STEPS_H_

#include "knotmm/stepper/StepWork.h"

namespace KnotMM {

/**
 * The fixed-step methods: euler, heun, midpoint and the Brownian euler_maruyama, ito_heun and
 * leimkuhler_matthews (knotmm.dynamics.deterministic and knotmm.dynamics.brownian, formula
 * for formula).
 */
class FixedSteps {
public:
    explicit FixedSteps(RPYBackend& backend);
    /** One step of h from work.y into work.y1; returns h. */
    double step(StepWork& work, double h);
    /**
     * leimkuhler_matthews's half kick drawn in the last step, used again in the next one while
     * the Context still has the positions that step ended at (checkpointed).
     */
    struct HeldKick {
        bool valid = false;
        VectorPtr kick, positions;
    } held;

private:
    VectorPtr k2, ytmp, w, sum;
};

} // namespace KnotMM

#endif
