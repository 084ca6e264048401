#ifndef KNOTMM_COMMON_RPY_BATCH_H_
#define KNOTMM_COMMON_RPY_BATCH_H_

// K copies of one system in one Context on OpenMM's device platforms (CopyBatch over
// CommonRPYBackend). Each copy's state, noise, step control and vector operations live on the
// device as in a run of that copy alone (a CommonRPYBackend of n beads; all copies share one
// compiled program). An evaluation gathers every copy's positions into one array with its
// centre of mass and reach (kernel gatherCopy, one launch per copy), writes all copies into
// the Context in one launch (writeCopies: each at its centre of mass, or on the grid when the
// copies are kept apart: then the reaches are the one download), evaluates the forces once,
// reads all forces in one launch, and gives each waiting copy mu(y) F from its own block
// (scatterCopy and mobilityTimes, one launch each per copy). Memory grows as K: the batch's
// arrays hold K n beads, each copy's backend its own n.

#include "CommonRPYBackend.h"
#include "knotmm/stepper/CopyBatch.h"

#include <vector>

namespace KnotMM {

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

protected:
    std::unique_ptr<RPYBackend> makeBackend(int copy, const RPYIntegrator& settings) override;
    void readContextPositions(OpenMM::ContextImpl& context, int copy, StateVector& positions) override;
    void evaluate(OpenMM::ContextImpl& context) override;

private:
    CommonRPYBackend& backendOf(int copy) { return static_cast<CommonRPYBackend&>(*copyAt(copy).backend); }
    /** The batch's kernels, from the first copy's program (after the copies are made). */
    void createKernels();
    OpenMM::ComputeContext& cc;
    int side = 1;                                  // copies per edge of the grid
    OpenMM::ComputeArray particleBead;             // particle -> bead among all copies', -1 for a site
    OpenMM::ComputeArray all, allForces, centres;  // K 3n, K 3n, 4 K doubles
    std::vector<double> hostCentres;
    bool readAll = false;                          // the Context's positions are in `all`
    OpenMM::ComputeKernel gatherKernel, writeKernel, scatterKernel, readPositionsKernel, readForcesKernel;
};

} // namespace KnotMM

#endif
