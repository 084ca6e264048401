#ifndef KNOTMM_REFERENCE_RPY_KERNELS_H_
#define KNOTMM_REFERENCE_RPY_KERNELS_H_

#include "RPYMobility.h"
#include "knotmm/RPYKernels.h"

#include <cstdint>
#include <map>
#include <vector>

namespace KnotMM {

/** xoshiro256** with Marsaglia-polar normals; its whole state goes into checkpoints. */
class NoiseStream {
public:
    void seed(uint64_t seed);
    uint64_t next();
    double uniform();  // in [0, 1)
    double normal();
    void write(std::ostream& stream) const;
    void read(std::istream& stream);
private:
    uint64_t s[4] = {0, 0, 0, 0};
    bool haveSpare = false;
    double spare = 0.0;
};

/**
 * Reference (double precision, CPU) implementation. It needs the Reference platform's
 * PlatformData (positions and forces as std::vector<Vec3>), which the CPU platform shares,
 * so the same factory is registered for both.
 */
class ReferenceIntegrateRPYStepKernel : public IntegrateRPYStepKernel {
public:
    ReferenceIntegrateRPYStepKernel(std::string name, const OpenMM::Platform& platform)
        : IntegrateRPYStepKernel(name, platform), mobility(1.0, 1.0, 1) {}
    void initialize(const OpenMM::System& system, const RPYIntegrator& integrator) override;
    double execute(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double targetTime) override;
    void computeGroupEnergies(OpenMM::ContextImpl& context, const std::vector<int>& groups,
                              std::vector<double>& energies) override;
    void invalidateCache() override;
    void createCheckpoint(std::ostream& stream) const override;
    void loadCheckpoint(std::istream& stream) override;
    long long getNumForceEvaluations() const override { return nEvaluations; }
    long long getNumAcceptedSteps() const override { return nAccepted; }
    long long getNumRejectedSteps() const override { return nRejected; }
    int getLastStages() const override { return lastStages; }
    double getSpectralRadius() const override { return haveRho ? rho : 0.0; }

    typedef std::vector<double> Vec;  // 3n numbers, bead-major (x0, y0, z0, x1, ...)

private:
    enum Method { EULER, HEUN, MIDPOINT, RK23, RKC2, EULER_MARUYAMA, ITO_HEUN, LEIMKUHLER_MATTHEWS };
    struct Chebyshev {
        std::vector<double> mu, nu, muT, gammaT;
    };
    void readPositions(OpenMM::ContextImpl& context, Vec& y) const;
    void writePositions(OpenMM::ContextImpl& context, const Vec& y, bool shift) const;
    void velocity(OpenMM::ContextImpl& context, const Vec& y, Vec& v);
    void keepK1(OpenMM::ContextImpl& context, const Vec& at);
    double stepFixed(OpenMM::ContextImpl& context, double h);
    double stepRK23(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double maxDt);
    double stepRKC2(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double maxDt);
    double spectralRadius(OpenMM::ContextImpl& context, const Vec& y, const Vec& f0);
    void noiseSample(const Vec& y, double scale, Vec& w);
    const Chebyshev& chebyshev(int s);
    double errorNorm(const Vec& err, double tolerance) const;

    Method method;
    int n = 0;
    std::vector<int> beadParticle;  // bead -> particle index (virtual sites are not beads)
    bool hasVirtualSites = false;
    double kT = 0.0;
    int numThreads = 1;
    RPYMobility mobility;
    NoiseStream noise;
    bool lanczos = false;          // the integrator's noise method (read at every step)
    double lanczosTolerance = 1e-6;
    LanczosSqrt lanczosSqrt;
    std::vector<OpenMM::Vec3> rkcStart;

    // state carried from step to step (all of it is checkpointed)
    Vec y, k1;          // positions of the step being taken; velocity at them (FSAL)
    bool haveK1 = false;
    Vec k1Positions;    // the positions and parameters k1 belongs to: it is reused only
    std::map<std::string, double> k1Parameters;  // while the Context still has exactly these
    double errOld = 1.0;  // rk23's PI controller memory
    double rho = 0.0, rkcErrOld = 0.0, rkcHOld = 0.0;
    bool haveRho = false, haveEig = false, haveRkcErrOld = false, haveRkcHOld = false;
    Vec eig;
    int stepsSinceRho = 0, lastStages = 0;
    long long nEvaluations = 0, nAccepted = 0, nRejected = 0;
    // leimkuhler_matthews: the half kick drawn in the last step, used again in the next one
    // while the Context still has the positions that step ended at (kickPositions)
    bool haveKick = false;
    Vec kick, kickPositions;

    // scratch
    Vec xs, fs, vs, zs, k2, k3, k4, y1, ytmp, err, w, xi, mat;
    std::vector<Vec> stage;
    std::map<int, Chebyshev> chebyshevCache;
};

} // namespace KnotMM

#endif
