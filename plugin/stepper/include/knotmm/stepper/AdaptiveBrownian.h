#ifndef KNOTMM_STEPPER_ADAPTIVE_BROWNIAN_H_
#define KNOTMM_STEPPER_ADAPTIVE_BROWNIAN_H_

#include "knotmm/stepper/StepWork.h"

#include <deque>
#include <vector>
#include <utility>

namespace KnotMM {

/**
 * Increments of one Wiener process over future intervals, earliest first
 * (knotmm.dynamics.adaptive_brownian.WienerQueue): what rejected and clipped steps left over.
 */
class WienerQueue {
public:
    explicit WienerQueue(RPYBackend& backend);
    /**
     * total = the increment over the next h (ps): queued intervals while they fit, one longer
     * interval split by the Brownian bridge, fresh increments beyond the queue.
     */
    void take(StepWork& work, double h, StateVector& total);
    /** Put the increment dw over the next h back at the front (a rejected step). */
    void giveBack(double h, const StateVector& dw);
    void clear() { pending.clear(); }
    std::deque<std::pair<double, VectorPtr>> pending;  // (span in ps, increment); checkpointed

private:
    RPYBackend& backend;
    VectorPtr xi, first;
    std::vector<VectorPtr> spare;  // vectors of used intervals, for giveBack (no allocation per step)
};

/**
 * ito_heun_adaptive: the Euler-Heun pair with PI step control and rejection sampling with
 * memory (knotmm.dynamics.adaptive_brownian.AdaptiveItoHeun, formula for formula):
 *   W = sqrt(2 kT) B(y) dW,  yE = y + h v(y) + W,  y1 = y + h/2 (v(y) + v(yE)) + W,
 *   err = h/2 (v(yE) - v(y)), controller exponents for an error of order h^(3/2).
 */
class AdaptiveBrownian {
public:
    explicit AdaptiveBrownian(RPYBackend& backend);
    double step(StepWork& work, double maxDt);
    double errOld = 1.0;  // the PI controller's memory (checkpointed)
    WienerQueue queue;

private:
    VectorPtr dw, w, yEuler, v1, diff, err;
};

} // namespace KnotMM

#endif
