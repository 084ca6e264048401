#ifndef KNOTMM_COMMON_RPY_BACKEND_H_
#define KNOTMM_COMMON_RPY_BACKEND_H_

// The stepper's backend on OpenMM's device platforms (OpenCL, CUDA, HIP), written once against
// OpenMM's common compute layer (ComputeContext, ComputeArray, kernels in the common kernel
// language of kernels/*.cc, compiled by the ComputeContext). Each platform's factory library
// (plugin/platforms/opencl/, cuda/) compiles this file against that platform's library.

#include "RPYMobility.h"
#include "knotmm/stepper/Backend.h"
#include "knotmm/stepper/StepperKernel.h"
#include "openmm/common/ComputeArray.h"
#include "openmm/common/ComputeContext.h"

#include <map>
#include <string>
#include <vector>

namespace KnotMM {

/** A vector of the device backend: 3n doubles in the device's memory. */
class CommonVector : public StateVector {
public:
    OpenMM::ComputeArray a;
};

/**
 * RPYBackend over a ComputeContext. Vectors are ComputeArrays of 3n doubles (bead-major). The
 * Context's positions (posq, in mixed precision also posqCorrection) and forces (the 64-bit
 * fixed-point force buffer) are read and written by kernels through the Context's atom order
 * (getAtomIndexArray, read on the device at each call, so a reordering by OpenMM is followed).
 * Velocities v = mu F by a device pair loop; the vector operations are kernels (combine: one
 * kernel per pattern of terms, compiled when first used); norms and tests are device
 * reductions with one small download each. Noise: normals drawn on the host from the
 * stepper's stream and uploaded; Cholesky on the host (the Reference backend's RPYMobility
 * matrix and choleskyLower), Lanczos with its Krylov loop on the host and each product mu v
 * on the device.
 *
 * Precision (the device must support double precision). Double: the Context holds the state
 * exactly. Mixed: the state the steps start from is what the Context holds, a float plus a
 * float correction per number (about 48 bits), so equal() compares two vectors as the Context
 * would store them; checkpoints continue bit for bit. Single: the Context's float positions
 * are scratch; the backend keeps the positions it last wrote in double and starts the next
 * step from them while the Context's positions are still the ones it wrote (a device
 * comparison each step), else from the Context's (changed from outside: setPositions, a
 * loaded checkpoint, which therefore continues from float positions, not bit for bit).
 */
class CommonRPYBackend : public RPYBackend {
public:
    CommonRPYBackend(OpenMM::ComputeContext& cc, const OpenMM::System& system, const RPYIntegrator& integrator);
    int numBeads() const override { return n; }
    VectorPtr createVector() override;
    void applySettings(const RPYIntegrator& integrator) override;
    void getPositions(OpenMM::ContextImpl& context, StateVector& y) override;
    void setPositions(OpenMM::ContextImpl& context, const StateVector& y) override;
    void velocity(OpenMM::ContextImpl& context, const StateVector& y, StateVector& v) override;
    void groupEnergies(OpenMM::ContextImpl& context, const std::vector<int>& groups,
                       std::vector<double>& energies) override;
    void factorNoise(const StateVector& y) override;
    void applyNoise(double scale, const StateVector& z, StateVector& out) override;
    void normals(NoiseStream& stream, StateVector& out) override;
    void combine(StateVector& out, std::initializer_list<Term> terms) override;
    void copy(StateVector& out, const StateVector& in) override;
    void setZero(StateVector& out) override;
    bool equal(const StateVector& a, const StateVector& b) override;
    double norm(const StateVector& v) override;
    double maxBeadNorm(const StateVector& v) override;
    int firstNonFinite(const StateVector& v) override;
    void download(const StateVector& v, std::vector<double>& host) override;
    void upload(const std::vector<double>& host, StateVector& v) override;

private:
    /** y = the positions the steps start from (getPositions). */
    void readState(OpenMM::ComputeArray& y);
    /** The Context's bead positions = y, minus their centre of mass if `shift`; virtual sites placed. */
    void writePositions(OpenMM::ComputeArray& y, bool shift);
    /** out = mu(x) f on the device. */
    void mobilityTimes(OpenMM::ComputeArray& x, OpenMM::ComputeArray& f, OpenMM::ComputeArray& out);
    OpenMM::ComputeKernel& combineKernel(const std::string& pattern, int count);

    OpenMM::ComputeContext& cc;
    int n = 0, numAtoms = 0;
    bool hasVirtualSites = false, mixed = false, single = false;
    bool haveShadow = false;  // single precision: shadow holds the positions posq was last written from
    double diameter, mu0;
    RPYMobility hostMobility;  // the dense matrix for Cholesky noise, on the host
    bool lanczos = false;
    double lanczosTolerance = 1e-6;
    LanczosSqrt lanczosSqrt;
    int tileSize, reduceSize;
    OpenMM::ComputeArray particleBead;                 // particle -> bead, -1 for a virtual site
    OpenMM::ComputeArray com, forces, scalars, counts;  // 3, 3n, 2 doubles; 1 int
    OpenMM::ComputeArray noiseAt, lanczosIn, lanczosOut, energyPosition;  // 3n doubles each
    OpenMM::ComputeArray savedPosq, savedPosqCorrection, savedForces;    // groupEnergies
    OpenMM::ComputeArray shadow, writtenPosq;                            // single precision
    OpenMM::ComputeKernel readPositionsKernel, writePositionsKernel, centreOfMassKernel, readForcesKernel,
        mobilityKernel, sumSquaresKernel, maxBeadSquareKernel, firstNonFiniteKernel, countDifferentKernel,
        countChangedKernel;
    std::map<std::string, std::string> defines;
    std::map<std::string, OpenMM::ComputeKernel> combineKernels;  // by pattern of terms
    std::vector<double> host, hostOut, noiseAtHost, mat;           // host scratch
};

/** The integrator's kernel on a device platform: the stepper over CommonRPYBackend. */
class CommonIntegrateRPYStepKernel : public StepperKernel {
public:
    CommonIntegrateRPYStepKernel(std::string name, const OpenMM::Platform& platform, OpenMM::ComputeContext& cc)
        : StepperKernel(name, platform), cc(cc) {}
    // The stepper's device work, each call with the ComputeContext made current (CUDA, HIP).
    double execute(OpenMM::ContextImpl& context, RPYIntegrator& integrator, double targetTime) override;
    void computeGroupEnergies(OpenMM::ContextImpl& context, const std::vector<int>& groups,
                              std::vector<double>& energies) override;
    void createCheckpoint(std::ostream& stream) const override;
    void loadCheckpoint(std::istream& stream) override;

protected:
    std::unique_ptr<RPYBackend> createBackend(const OpenMM::System& system, const RPYIntegrator& integrator) override;

private:
    OpenMM::ComputeContext& cc;
};

} // namespace KnotMM

#endif
