#ifndef KNOTMM_STEPPER_RK23_H_
#define KNOTMM_STEPPER_RK23_H_

#include "knotmm/stepper/StepWork.h"

namespace KnotMM {

/** Bogacki-Shampine 3(2), FSAL, with PI step control (knotmm.dynamics.deterministic.RK23). */
class RK23Control {
public:
    explicit RK23Control(RPYBackend& backend);
    /** One accepted step of at most maxDt from work.y into work.y1; returns it. */
    double step(StepWork& work, double maxDt);
    double errOld = 1.0;  // the PI controller's memory (checkpointed)

private:
    VectorPtr k2, k3, k4, ytmp, err;
};

} // namespace KnotMM

#endif
