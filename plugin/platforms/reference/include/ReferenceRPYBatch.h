#ifndef KNOTMM_REFERENCE_RPY_BATCH_H_
#define KNOTMM_REFERENCE_RPY_BATCH_H_

// K copies of one system in one Context on the Reference and CPU platforms (RPYCopies,
// RPYIntegrator::setNumCopies). Each copy is a Stepper of its own over a CopyBackend: its own
// positions, time, step size, step control and noise stream, every method's formulas as in a
// run of that copy alone. The copies take their steps side by side: each runs in a fiber
// (POSIX ucontext) that gives control back whenever its step needs a velocity; once every
// copy still stepping waits for one, the Context evaluates all copies' forces in one call,
// with each copy moved to its own place on a grid (its centre of mass at a grid point, the
// points farther apart than the copies are wide plus twice the largest cutoff, so no force
// reaches from one copy to another), or, with copiesApart = false, each copy at its own
// centre of mass as one system alone is evaluated (the System's interaction groups keep the
// copies apart: a copy's forces are then those of the copy alone, bit for bit whatever the
// others do), and each copy multiplies its own forces by its own
// block of the mobility. A copy that lands on its target, or fails, waits while the others
// go on. The fibers take turns on the calling thread; what they wait for, the mobility
// products and the Cholesky factorisations of all copies, is shared out over the
// integrator's threads (each copy's numbers are the same whatever the threads).

#include "ReferenceRPYBackend.h"
#include "knotmm/RPYKernels.h"
#include "knotmm/stepper/Stepper.h"

#include <chrono>
#include <exception>
#include <memory>
#include <string>
#include <ucontext.h>
#ifdef __linux__
#include <sched.h>
#endif
#include <vector>

namespace OpenMM {
class ThreadPool;
}

namespace KnotMM {

class ReferenceRPYBatch;

/** A copy's backend: its positions live in the batch, its velocity waits for the batch's forces. */
class CopyBackend : public ReferenceRPYBackend {
public:
    CopyBackend(ReferenceRPYBatch& batch, int copy, int numBeads, const RPYIntegrator& integrator)
        : ReferenceRPYBackend(numBeads, integrator), batch(batch), copy(copy) {}
    void getPositions(OpenMM::ContextImpl& context, StateVector& y) override;
    void setPositions(OpenMM::ContextImpl& context, const StateVector& y) override;
    bool holds(OpenMM::ContextImpl& context, const StateVector& y) override;
    void velocity(OpenMM::ContextImpl& context, const StateVector& y, StateVector& v) override;
    void groupEnergies(OpenMM::ContextImpl& context, const StateVector& at, const std::vector<int>& groups,
                       std::vector<double>& energies) override;
    /** Cholesky with the batch's threads: factorised by them beside the other copies' work; else as alone. */
    void factorNoise(const StateVector& y) override;
    /** The batch's jobs for this copy, run on one of its threads. */
    void velocityJob(const std::vector<double>& y, const std::vector<OpenMM::Vec3>& forces, std::vector<double>& out) {
        mobilityTimes(y, forces, 0, out);
    }
    void factorJob(const std::vector<double>& y);

private:
    ReferenceRPYBatch& batch;
    int copy;
};

class ReferenceRPYBatch : public RPYCopies {
public:
    ReferenceRPYBatch(const OpenMM::System& system, const RPYIntegrator& integrator);
    ~ReferenceRPYBatch();
    int numCopies() const override { return (int) copies.size(); }
    int beadsPerCopy() const override { return n; }
    bool stepTo(OpenMM::ContextImpl& context, RPYIntegrator& integrator, const std::vector<double>& targets,
                double maxSeconds) override;
    std::vector<double> getPositions(int copy) const override { return copies[copy]->positions; }
    void setPositions(int copy, const std::vector<double>& positions) override;
    double getTime(int copy) const override { return copies[copy]->time; }
    void setTime(int copy, double time) override { copies[copy]->time = time; }
    void createCheckpoint(int copy, std::ostream& stream) const override;
    void loadCheckpoint(int copy, std::istream& stream) override;
    std::string faultKind(int copy) const override { return copies[copy]->faultKind; }
    std::string faultMessage(int copy) const override { return copies[copy]->faultMessage; }
    void clearFault(int copy) override;
    double spacing() const override { return gridSpacing; }

private:
    friend class CopyBackend;
    enum class State { Idle, Runnable, WaitingForForces, WaitingForFactor, Done };
    struct Copy {
        std::unique_ptr<RPYIntegrator> settings;  // step size and settings of this copy alone
        std::unique_ptr<CopyBackend> backend;
        std::unique_ptr<Stepper> stepper;
        std::vector<double> positions;            // 3n, bead-major, nm
        double time = 0.0, target = 0.0;
        State state = State::Idle;
        const std::vector<double>* request = nullptr;  // where the copy wants its forces
        std::vector<OpenMM::Vec3> forces;              // its beads' forces at `request`
        std::vector<double> velocity;                  // mu F at `request` (the batch's job)
        std::exception_ptr jobError;                   // the job's failure, rethrown in the fiber
        std::string faultKind, faultMessage;
        ucontext_t fiber;
        std::unique_ptr<char[]> stack;
        bool placed = false;  // positions and time given (or taken from the Context)
    };
    static void fiberEntry(int low, int high);
    void runCopy(Copy& c);
    /** Called by a copy's fiber: wait for the forces at y; then c.forces hold them. */
    void waitForForces(Copy& c, const std::vector<double>& y);
    /** Called by a copy's fiber: wait until its noise factor at y is made. */
    void waitForFactor(Copy& c, const std::vector<double>& y);
    void evaluateForces(OpenMM::ContextImpl& context);
    /** The waiting copies' mobility products and factorisations, shared out over the threads. */
    void runJobs();
    void startThreads();
    int n = 0;                          // beads per copy
    std::vector<int> beadParticle;      // bead (all copies) -> particle
    bool hasVirtualSites = false;
    double margin = 1.0;                // nm: twice the largest nonbonded cutoff
    bool apart = true;                  // copies on a grid (else each at its centre of mass)
    double gridSpacing = 0.0;           // nm: 0 until the first evaluation sets it
    int gridSide = 1;
    std::vector<std::unique_ptr<Copy>> copies;
    ucontext_t scheduler;
    Copy* running = nullptr;
    OpenMM::ContextImpl* context = nullptr;
    std::string forceError;             // the last evaluation's failure, "" when it succeeded
    int threads = 1;                            // the integrator's, over the copies
    std::unique_ptr<OpenMM::ThreadPool> pool;  // made at the first jobs (startThreads)
#ifdef __linux__
    cpu_set_t cores;                            // the process's cores when the batch was made
#endif
    std::chrono::steady_clock::time_point start;
    double budget = 0.0;
};

} // namespace KnotMM

#endif
