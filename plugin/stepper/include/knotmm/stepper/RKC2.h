#ifndef KNOTMM_STEPPER_RKC2_H_
#define KNOTMM_STEPPER_RKC2_H_

#include "knotmm/stepper/StepWork.h"
#include "openmm/Vec3.h"

#include <map>
#include <vector>

namespace KnotMM {

/** Coefficients of the damped s-stage second-order Chebyshev method. */
struct ChebyshevCoefficients {
    std::vector<double> mu, nu, muT, gammaT;
};

/** Damped s-stage RKC2 coefficients (knotmm.dynamics.deterministic._chebyshev_coefficients). */
ChebyshevCoefficients chebyshevCoefficients(int stages);

/**
 * Damped second-order Runge-Kutta-Chebyshev with error control
 * (knotmm.dynamics.deterministic.RKC2): the stages follow the spectral radius of the
 * velocity's Jacobian, estimated by a nonlinear power iteration every 25 steps and after every
 * rejection.
 */
class RKC2Control {
public:
    /** `start`: the power iteration's first vector (empty: a fixed pseudo-random one). */
    RKC2Control(RPYBackend& backend, const std::vector<OpenMM::Vec3>& start);
    double step(StepWork& work, double maxDt);
    /** Estimate the spectral radius again before the next step. */
    void forgetSpectralRadius() { haveRho = false; }
    double spectralRadiusEstimate() const { return haveRho ? rho : 0.0; }
    /** The power iteration's estimate at work.y, where the velocity is f0 (the state kept). */
    double estimate(StepWork& work, const StateVector& f0) { return spectralRadius(work, f0); }

    // checkpointed state
    double rho = 0.0, errOld = 0.0, hOld = 0.0;
    bool haveRho = false, haveErrOld = false, haveHOld = false;
    int stepsSinceRho = 0, lastStages = 0;
    bool haveEig = false;
    VectorPtr eig;  // the power iteration's last vector: where the next one starts

private:
    double spectralRadius(StepWork& work, const StateVector& f0);
    const ChebyshevCoefficients& chebyshev(int stages);
    std::vector<OpenMM::Vec3> start;
    std::map<int, ChebyshevCoefficients> cache;
    VectorPtr k2, k4, ytmp, err, sum, prev, prev2, probe, dv, v;
};

} // namespace KnotMM

#endif
