#ifndef KNOTMM_REFERENCE_RPY_BATCH_H_
#define KNOTMM_REFERENCE_RPY_BATCH_H_

// K copies of one system in one Context on the Reference and CPU platforms (CopyBatch): the
// copies' forces in one evaluation of the Context's host arrays; what the copies then wait
// for, the mobility products and the Cholesky factorisations of all copies, is shared out
// over the integrator's threads (each copy's numbers are the same whatever the threads).

#include "ReferenceRPYBackend.h"
#include "knotmm/stepper/CopyBatch.h"

#include <memory>
#include <vector>

namespace KnotMM {

class ReferenceRPYBatch;

/** A copy's backend on the host; its Cholesky factorisations go to the batch's threads. */
class CopyBackend : public BatchedBackend<ReferenceRPYBackend> {
public:
    CopyBackend(ReferenceRPYBatch& batch, int copy, int numBeads, const RPYIntegrator& integrator, int threads,
                bool singleForces);
    /** Cholesky with the batch's threads: factorised by them beside the other copies' work; else as alone. */
    void factorNoise(const StateVector& y) override;
    /** The batch's jobs for this copy, run on one of its threads. */
    void velocityJob(const std::vector<double>& y, const std::vector<OpenMM::Vec3>& forces, std::vector<double>& out) {
        mobilityTimes(y, forces, 0, out);
    }
    void factorJob(const StateVector& y) { ReferenceRPYBackend::factorNoise(y); }

private:
    int threads;  // the batch's
};

class ReferenceRPYBatch : public CopyBatch {
public:
    /** `singleForces`: as for ReferenceRPYBackend (the CPU platform). */
    ReferenceRPYBatch(const OpenMM::System& system, const RPYIntegrator& integrator, bool singleForces);

protected:
    std::unique_ptr<RPYBackend> makeBackend(int copy, const RPYIntegrator& settings) override;
    void readContextPositions(OpenMM::ContextImpl& context, int copy, StateVector& positions) override;
    void evaluate(OpenMM::ContextImpl& context) override;
    /** The waiting copies' mobility products and factorisations, shared out over the threads. */
    void runJobs() override;

private:
    bool singleForces;
    std::vector<std::vector<OpenMM::Vec3>> forces;  // each copy's beads' forces at its request
    // scratch of evaluate and runJobs: each copy's positions and centre, the waiting copies
    std::vector<const std::vector<double>*> at;
    std::vector<OpenMM::Vec3> centre;
    std::vector<int> jobs;
};

} // namespace KnotMM

#endif
