#ifndef KNOTMM_COMMON_RPY_BATCH_H_
#define KNOTMM_COMMON_RPY_BATCH_H_

// K copies of one system in one Context on OpenMM's device platforms (CopyBatch over
// CommonRPYBackend), launched for all copies at once. Every copy's vectors live in one device
// array, the arena (CopyArena: 3n doubles a vector at an offset of its own, free slots kept per
// copy), so one launch can reach every copy's. A copy's vector operations (combine, copy,
// setZero) are not launched when its stepper asks for them: they are recorded, and each round
// of the batch (settle) launches them for all copies at once, the i-th operation of every copy
// in one launch per pattern of terms (combineCopies, each copy with its own offsets and
// coefficients; one upload of the round's table). A copy waits for the round where its stepper
// needs a result: a velocity (one gather of all copies' positions with their centres and
// reaches, one write into the Context, one force call, one read of all forces, one mobility
// launch for every waiting copy's block), a try's check (one launch and one download for every
// waiting copy, with the centres' download when the copies are kept apart), Cholesky noise
// (every waiting copy's factor point and z in one download, each copy's factor and B z on the
// host over the integrator's threads, one upload of the replies; counter-based normals are
// recorded with the vector operations), or any other operation (Lanczos noise, norms,
// transfers), which then runs for that copy alone on scratch vectors (the copy's
// CommonRPYBackend, as a run of that copy alone). So a round costs about as many launches as
// one step of a single run, whatever K. Each copy's numbers are those of its run
// alone: the same operations in the same order on the same numbers. Memory grows as K.

#include "CommonRPYBackend.h"
#include "knotmm/stepper/CopyBatch.h"

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace KnotMM {

class CommonRPYBatch;

/** The copies' vectors in one device array: slots of 3n doubles, each slot one copy's. */
struct CopyArena {
    CopyArena(OpenMM::ComputeContext& cc, int stride, int copies);
    /** A free slot of `copy` (the array grows, its numbers kept, when none is free). */
    int take(int copy);
    /** The slot is free again, for `copy` only (its pending operations keep their order). */
    void give(int copy, int slot) { freeSlots[copy].push_back(slot); }
    /** to[toAt ..] = from[fromAt ..], count numbers (one launch of moveNumbers). */
    void moveNumbers(OpenMM::ComputeArray& from, int fromAt, OpenMM::ComputeArray& to, int toAt, int count);
    OpenMM::ComputeContext& cc;
    const int stride;                               // 3n
    std::unique_ptr<OpenMM::ComputeArray> numbers;  // capacity x stride doubles
    OpenMM::ComputeKernel move;                     // moveNumbers, to grow
    int capacity = 0, used = 0;                     // slots
    std::vector<std::vector<int>> freeSlots;        // per copy
};

/**
 * A vector operation a copy recorded (combine, copy: one term of 1, setZero: pattern "z",
 * normals of a counter-based stream: pattern "n", c = the key's and the draw's 32-bit halves).
 */
struct DeferredOp {
    std::string pattern;  // 'm' (c v) or 'd' (v / c) per term; "z": zero; "n": normals
    int out = 0;          // arena offsets
    int in[8] = {0};
    double c[8] = {0.0};
};

/** A copy's backend: its vectors in the arena, its vector operations recorded for the round. */
class ArenaBackend : public BatchedBackend<CommonRPYBackend> {
public:
    ArenaBackend(CommonRPYBatch& batch, int copy, OpenMM::ComputeContext& cc, int numBeads,
                 const RPYIntegrator& integrator, const CommonRPYBackend* prototype);
    VectorPtr createVector() override;
    void combine(StateVector& out, std::initializer_list<Term> terms) override;
    void copy(StateVector& out, const StateVector& in) override;
    void setZero(StateVector& out) override;
    TryCheck checkTry(const StateVector& err, const StateVector& y1) override;
    int firstNonFinite(const StateVector& v) override;
    // for the copy alone, on the batch's scratch vectors (its recorded operations done first)
    bool equal(const StateVector& a, const StateVector& b) override;
    double norm(const StateVector& v) override;
    double maxBeadNorm(const StateVector& v) override;
    void factorNoise(const StateVector& y) override;
    void applyNoise(double scale, const StateVector& z, StateVector& out) override;
    void normals(NoiseStream& stream, StateVector& out) override;
    void download(const StateVector& v, std::vector<double>& host) override;
    void upload(const std::vector<double>& host, StateVector& v) override;
    // Cholesky noise in a fiber: factorNoise records y (factorPoint), applyNoise waits for the
    // round, which factors at it (once) and makes B z for every waiting copy with one download
    // and one upload. Lanczos noise, and any call outside stepTo, runs for the copy alone.
    VectorPtr factorPoint;       // y of the factor to make, in the arena
    bool factorPending = false;  // factorPoint holds a y not factored yet
    bool usesLanczos() const { return lanczos; }

private:
    CommonRPYBatch& owner;
};

class CommonRPYBatch : public CopyBatch {
public:
    CommonRPYBatch(OpenMM::ComputeContext& cc, const OpenMM::System& system, const RPYIntegrator& integrator);
    // each with the ComputeContext made current (CUDA, HIP)
    bool stepTo(OpenMM::ContextImpl& context, RPYIntegrator& integrator, const std::vector<double>& targets,
                double maxSeconds) override;
    std::vector<double> getPositions(int copy) const override;
    void setPositions(int copy, const std::vector<double>& positions) override;
    void createCheckpoint(int copy, std::ostream& stream) const override;
    void loadCheckpoint(int copy, std::istream& stream) override;

    // --- for the copies' backends ----------------------------------------------------------
    CopyArena& arenaOf() { return *arena; }
    std::shared_ptr<CopyArena> sharedArena() { return arena; }
    /** Record copy's operation for the round. */
    void defer(int copy, DeferredOp&& op) { pending[copy].push_back(std::move(op)); }
    /** Copy's recorded operations done (in a fiber: wait for the round; outside: now). */
    void settleCopy(int copy);
    /** Scratch vector k (0-2) = the arena vector v (settleCopy first). */
    CommonVector& stage(int k, const StateVector& v);
    /** The arena vector v = scratch vector k. */
    void unstage(int k, StateVector& v);
    /** The scratch vector k, to be written. */
    CommonVector& scratchVector(int k) { return *scratch[k]; }
    /** The scale of copy's noise request (waitForNoise). */
    void setNoiseScale(int copy, double scale) { noiseScale[copy] = scale; }

protected:
    std::unique_ptr<RPYBackend> makeBackend(int copy, const RPYIntegrator& settings) override;
    void readContextPositions(OpenMM::ContextImpl& context, int copy, StateVector& positions) override;
    void settle() override;
    void evaluate(OpenMM::ContextImpl& context) override;

private:
    ArenaBackend& backendOf(int copy) { return static_cast<ArenaBackend&>(*copyAt(copy).backend); }
    /** The copies waiting for noise: factors where pending, then B z, one download, one upload. */
    void makeNoise();
    /** The batch's kernels, from the first copy's program (before any vector is made). */
    void createKernels(const CommonRPYBackend& first);
    /** combineCopies for a pattern of terms, compiled when first used. */
    OpenMM::ComputeKernel& combineKernel(const std::string& pattern);
    /** Launch every copy's recorded operations, the i-th of all copies together by pattern. */
    void launchPending();
    /** Append to the round's table; returns where it starts. */
    int tableAt() const { return (int) hostTable.size(); }
    void uploadTable();
    OpenMM::ComputeContext& cc;
    int side = 1;                                  // copies per edge of the grid
    std::shared_ptr<CopyArena> arena;
    std::vector<std::vector<DeferredOp>> pending;  // per copy, in order
    std::vector<std::unique_ptr<CommonVector>> scratch;
    OpenMM::ComputeArray particleBead;             // particle -> bead among all copies', -1 for a site
    OpenMM::ComputeArray all, allForces, centres;  // K 3n, K 3n, 4 K doubles
    OpenMM::ComputeArray table, checks;            // the round's table; 3 K doubles
    OpenMM::ComputeArray bulk;                     // noise requests and replies, 3n doubles each
    std::vector<double> hostTable, hostCentres, hostChecks, hostBulk, hostNoise, noiseScale;
    // a round's scratch, members so that a round allocates nothing once the copies have all
    // waited at once (strings of up to 15 terms stay in their small-string storage)
    struct Launch {
        std::string pattern;
        int base, copies;
    };
    std::vector<Launch> launches;
    std::vector<char> done, noiseFailed;
    std::vector<int> checking, noisy, waiting, factorEntry, zEntry, noiseJobs;
    bool readAll = false;                          // the Context's positions are in `all`
    OpenMM::ComputeKernel gatherKernel, writeKernel, readPositionsKernel, readForcesKernel, mobilityKernel,
        checkKernel, normalsKernel, collectKernel, spreadKernel;
    std::map<std::string, OpenMM::ComputeKernel> combineKernels;
    std::map<std::string, OpenMM::ComputeProgram> combinePrograms;
};

} // namespace KnotMM

#endif
