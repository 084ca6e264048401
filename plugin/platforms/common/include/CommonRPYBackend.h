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
#include <memory>
#include <string>
#include <vector>

namespace KnotMM {

struct CopyArena;

/**
 * A vector of the device backend: 3n doubles in the device's memory, its own array `a`, or (a
 * copy of a batch, CommonRPYBatch) a slot of the batch's arena, given back when it goes.
 */
class CommonVector : public StateVector {
public:
    ~CommonVector();
    OpenMM::ComputeArray a;
    std::shared_ptr<CopyArena> arena;  // null: the numbers are in `a`
    int copy = -1, slot = -1;
    int offset = 0;                    // where its numbers start in the arena
};
inline int arenaOffset(const StateVector& v) { return static_cast<const CommonVector&>(v).offset; }

/** The device array of a vector (kernels take arrays by non-const reference; inputs are never written). */
inline OpenMM::ComputeArray& data(StateVector& v) { return static_cast<CommonVector&>(v).a; }
inline OpenMM::ComputeArray& data(const StateVector& v) {
    return const_cast<OpenMM::ComputeArray&>(static_cast<const CommonVector&>(v).a);
}

/**
 * RPYBackend over a ComputeContext. Vectors are ComputeArrays of 3n doubles (bead-major). The
 * Context's positions (posq, in mixed precision also posqCorrection) and forces (the 64-bit
 * fixed-point force buffer) are read and written by kernels through the Context's atom order
 * (getAtomIndexArray, read on the device at each call, so a reordering by OpenMM is followed).
 * Velocities v = mu F by a device pair loop; the vector operations are kernels (combine: one
 * kernel per pattern of terms, compiled when first used); norms and tests are device
 * reductions with one small download each. Noise: a counter-based stream's normals made on
 * the device (kernel counterNormals, Philox.h's numbers), a sequential stream's (a run resumed
 * from a layout-5 checkpoint) drawn on the host and uploaded; Cholesky on the host (the Reference backend's RPYMobility
 * matrix and choleskyLower); Lanczos with its Krylov loop on the device (src/CommonRPYNoise.cpp:
 * products, dot products, Gram-Schmidt and norms there; alpha and beta downloaded together
 * once per iteration for the small tridiagonal problem, LanczosSmallProblem, on the host).
 *
 * Precision (the device must support double precision). The stepper keeps the state in
 * double on the device in every precision (Backend.h); the Context's positions are what it
 * writes after a step (double: exactly; mixed: a float plus a float correction per number,
 * about 48 bits; single: a float) and the scratch of each force evaluation (shifted to the
 * centre of mass). holds() and equal() compare as the Context stores positions, so positions
 * read back from the Context and set again count as unchanged; checkpoints hold the state and
 * continue bit for bit in every precision.
 */
class CommonRPYBackend : public RPYBackend {
public:
    CommonRPYBackend(OpenMM::ComputeContext& cc, const OpenMM::System& system, const RPYIntegrator& integrator);
    /**
     * A copy of a batch (CommonRPYBatch): `numBeads` beads whose positions and forces the batch
     * moves to and from the Context; the programs of `prototype` (another copy) when given.
     */
    CommonRPYBackend(OpenMM::ComputeContext& cc, int numBeads, const RPYIntegrator& integrator,
                     const CommonRPYBackend* prototype);
    int numBeads() const override { return n; }
    VectorPtr createVector() override;
    void applySettings(const RPYIntegrator& integrator) override;
    void getPositions(OpenMM::ContextImpl& context, StateVector& y) override;
    void setPositions(OpenMM::ContextImpl& context, const StateVector& y) override;
    bool holds(OpenMM::ContextImpl& context, const StateVector& y) override;
    void velocity(OpenMM::ContextImpl& context, const StateVector& y, StateVector& v) override;
    void groupEnergies(OpenMM::ContextImpl& context, const StateVector& at, const std::vector<int>& groups,
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
    TryCheck checkTry(const StateVector& err, const StateVector& y1) override;
    void download(const StateVector& v, std::vector<double>& host) override;
    void upload(const std::vector<double>& host, StateVector& v) override;

private:
    friend class CommonRPYBatch;
    friend class ArenaBackend;
    /** A try's check from the checkTry kernel's result (checkCopies writes the same three). */
    TryCheck tryCheckOf(const double result[3]) const;
    /** The Cholesky factor of mu(y), y on the host (3n numbers, bead-major). */
    void factorAt(const double* y);
    void setUp(const RPYIntegrator& integrator, const CommonRPYBackend* prototype);
    /** The fixed arguments of the kernels that read and write the Context. */
    void bindContext();
    /** y = the Context's bead positions. */
    void readPositions(OpenMM::ComputeArray& y);
    /** The number of i with a_i != b_i, as the Context stores positions (countDifferent in kernels/rpy.cc). */
    int countDifferent(OpenMM::ComputeArray& a, OpenMM::ComputeArray& b);
    /** The Context's bead positions = y, minus their centre of mass if `shift`; virtual sites placed. */
    void writePositions(OpenMM::ComputeArray& y, bool shift);
    /** out = mu(x) f on the device. */
    void mobilityTimes(OpenMM::ComputeArray& x, OpenMM::ComputeArray& f, OpenMM::ComputeArray& out);
    OpenMM::ComputeKernel& combineKernel(const std::string& pattern, int count);
    /** out = scale mu(noiseAt)^(1/2) z by Lanczos on the device (CommonRPYNoise.cpp). */
    void lanczosNoise(double scale, OpenMM::ComputeArray& z, OpenMM::ComputeArray& out);

    OpenMM::ComputeContext& cc;
    int n = 0, numAtoms = 0;
    bool hasVirtualSites = false, mixed = false, single = false;
    double diameter, mu0;
    RPYMobility hostMobility;  // the dense matrix for Cholesky noise, on the host
    bool lanczos = false;
    double lanczosTolerance = 1e-6;
    LanczosSmallProblem lanczosSmall;
    OpenMM::ComputeArray basis, proj, lanczosScalars;  // Krylov vectors, projections, alpha and beta: at first use
    int tileSize, reduceSize;
    OpenMM::ComputeArray particleBead;                 // particle -> bead, -1 for a virtual site
    OpenMM::ComputeArray com, forces, scalars, counts;  // 3, 3n, 3 doubles; 1 int
    OpenMM::ComputeArray noiseAt, lanczosV, lanczosW, energyPosition;  // 3n doubles each
    OpenMM::ComputeArray savedPosq, savedPosqCorrection, savedForces;    // groupEnergies
    OpenMM::ComputeKernel readPositionsKernel, writePositionsKernel, centreOfMassKernel, readForcesKernel,
        mobilityKernel, sumSquaresKernel, firstNonFiniteKernel, countDifferentKernel,
        checkTryKernel, lanczosDotsKernel, lanczosSubtractKernel, lanczosAlphaBetaKernel, lanczosScaleKernel,
        lanczosCombineKernel, counterNormalsKernel;
    std::map<std::string, std::string> defines;
    OpenMM::ComputeProgram program;                                // kernels/rpy.cc, shared by a batch's copies
    std::shared_ptr<std::map<std::string, OpenMM::ComputeProgram>> combinePrograms;  // by pattern, shared too
    std::map<std::string, OpenMM::ComputeKernel> combineKernels;  // by pattern of terms
    std::vector<double> host, hostOut, noiseAtHost;                // host scratch
    CholeskyFactor cholesky;                                       // the noise factor, on the host
    bool singleFactor = false;                                     // it in float, else in double
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
    std::unique_ptr<RPYCopies> createCopies(const OpenMM::System& system, const RPYIntegrator& integrator) override;

private:
    OpenMM::ComputeContext& cc;
};

} // namespace KnotMM

#endif
