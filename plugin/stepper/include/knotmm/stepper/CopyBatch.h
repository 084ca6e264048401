#ifndef KNOTMM_STEPPER_COPY_BATCH_H_
#define KNOTMM_STEPPER_COPY_BATCH_H_

// K copies of one system in one Context (RPYCopies, RPYIntegrator::setNumCopies), on any
// platform. Each copy is a Stepper of its own over a backend of its own (BatchedBackend):
// its own positions, time, step size, step control and noise stream, every method's formulas
// as in a run of that copy alone. The copies take their steps side by side: each runs in a
// fiber (POSIX ucontext) that gives control back whenever its step needs a velocity; once
// every copy still stepping waits for one, the platform (evaluate) evaluates all copies'
// forces in one call of the Context, with each copy moved to its own place on a grid (its
// centre of mass at a grid point, the points farther apart than the copies are wide plus
// twice the largest cutoff, so no force reaches from one copy to another), or, with
// copiesApart = false, each copy at its own centre of mass as one system alone is evaluated
// (the System's interaction groups keep the copies apart: a copy's forces are then those of
// the copy alone, bit for bit whatever the others do), and each copy's velocity is its own
// forces times its own block of the mobility. A copy that lands on its target, or fails,
// waits while the others go on. The fibers take turns on the calling thread. A round: every
// runnable copy runs until it waits (for a velocity, a noise factor or sample, a try's check,
// or for the operations it deferred to be done), then the platform settles (settle: the
// deferred operations, the noise, the checks), evaluates and runs its jobs, and the waiting
// copies go on.
//
// What a platform adds: its copies' backends (makeBackend), reading a copy's positions from
// the Context as it was created (readContextPositions), and the evaluation (evaluate, and
// runJobs for work it shares out over threads). platforms/reference/ReferenceRPYBatch (the
// Reference and CPU platforms) and platforms/common/CommonRPYBatch (OpenCL, CUDA).

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYKernels.h"
#include "knotmm/stepper/Backend.h"
#include "knotmm/stepper/Stepper.h"
#include "openmm/OpenMMException.h"

#include <chrono>
#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <ucontext.h>
#include <utility>
#include <vector>
#ifdef __linux__
#include <sched.h>
#endif

namespace OpenMM {
class System;
class ThreadPool;
}

namespace KnotMM {

class CopyBatch : public RPYCopies {
public:
    ~CopyBatch();
    int numCopies() const override { return (int) copies.size(); }
    int beadsPerCopy() const override { return n; }
    bool stepTo(OpenMM::ContextImpl& context, RPYIntegrator& integrator, const std::vector<double>& targets,
                double maxSeconds) override;
    std::vector<double> getPositions(int copy) const override;
    void setPositions(int copy, const std::vector<double>& positions) override;
    double getTime(int copy) const override { return copies[copy]->time; }
    void setTime(int copy, double time) override { copies[copy]->time = time; }
    void createCheckpoint(int copy, std::ostream& stream) const override;
    void loadCheckpoint(int copy, std::istream& stream) override;
    std::string faultKind(int copy) const override { return copies[copy]->faultKind; }
    std::string faultMessage(int copy) const override { return copies[copy]->faultMessage; }
    void clearFault(int copy) override;
    double spacing() const override { return gridSpacing; }

    // --- for the copies' backends (called in a copy's fiber) -----------------------------
    /** Wait until the batch has made v = mu(y) F(y) for the copy. */
    void waitForVelocity(int copy, const StateVector& y, StateVector& v);
    /** Wait until the batch has made the copy's noise factor at y (runJobs). */
    void waitForFactor(int copy, const StateVector& y);
    /** Wait until the batch has made checkTry(err, y1) for the copy (err null: y1's check alone). */
    RPYBackend::TryCheck waitForCheck(int copy, const StateVector* err, const StateVector& y1);
    /** Wait until the batch has made out = B z, the copy's noise (settle; request z, reply out). */
    void waitForNoise(int copy, const StateVector& z, StateVector& out);
    /** Wait until the batch has done the copy's deferred work (settle). */
    void waitForSettle(int copy);
    /** True while copy's fiber runs (its backend's calls can wait); false outside stepTo. */
    bool inFiberOf(int copy) const { return running == copies[copy].get(); }
    /** The copy's positions (what its stepper last wrote, or was given). */
    StateVector& positionsOf(int copy) { return *copies[copy]->positions; }

protected:
    /** The checks and the layout of the copies; the derived class then calls createCopies. */
    CopyBatch(const OpenMM::System& system, const RPYIntegrator& integrator);
    /** Make the copies' settings, backends (makeBackend) and steppers. */
    void createCopies(const RPYIntegrator& integrator);
    /** Copy k's backend, a BatchedBackend over the platform's backend. */
    virtual std::unique_ptr<RPYBackend> makeBackend(int copy, const RPYIntegrator& settings) = 0;
    /** positions = copy k's beads in the Context as it was created (a copy never given any). */
    virtual void readContextPositions(OpenMM::ContextImpl& context, int copy, StateVector& positions) = 0;
    /**
     * All copies' forces in one evaluation of the Context (a waiting copy at its request, the
     * others at their positions), each copy placed by placement(); then, for each waiting
     * copy, its reply = mu(request) F here or in runJobs. On failure: forceError set.
     */
    virtual void evaluate(OpenMM::ContextImpl& context) = 0;
    /**
     * The Context's forces of the integration force groups, virtual sites placed first when
     * the System has them (`placeSites`); false, with forceError set, when that fails.
     */
    bool calcForces(OpenMM::ContextImpl& context, const std::function<void()>& placeSites);
    /** Work the waiting copies left for after evaluate (velocities, factors); default none. */
    virtual void runJobs() {}
    /**
     * First in each round, and once after the last: the work the copies deferred (a platform
     * that defers its vector operations to launch them for all copies at once), then what
     * they wait for besides velocities and factors (WaitingForCheck: request2 = err or null,
     * request = y1, the result into `check`; WaitingForNoise: request = z, reply = out). Only
     * a platform whose backends defer or wait so (CommonRPYBatch) has any; default: nothing.
     */
    virtual void settle() {}
    /** The grid spacing for copies reaching `reach` (nm) from their centres; also sets spacing(). */
    double placeCopies(double reach);
    /** Copy k's grid point (nm), for the spacing placeCopies set. */
    void gridOffset(int copy, double offset[3]) const;
    /**
     * work(k) for each k in `jobs`, shared out over the integrator's threads (a pool made at
     * the first call with two jobs or more; each of its threads takes the cores the process
     * had when the batch was made), or here, one after another, with one thread or one job.
     * A job's exception is its own to keep (work must not throw).
     */
    void shareOut(const std::vector<int>& jobs, const std::function<void(int)>& work);

    enum class State {
        Idle, Runnable, WaitingForVelocity, WaitingForFactor, WaitingForCheck, WaitingForNoise,
        WaitingToSettle, Done
    };
    struct Copy {
        std::unique_ptr<RPYIntegrator> settings;  // step size and settings of this copy alone
        std::unique_ptr<RPYBackend> backend;
        std::unique_ptr<Stepper> stepper;
        VectorPtr positions;                      // 3n, in the backend's memory
        double time = 0.0, target = 0.0;
        State state = State::Idle;
        const StateVector* request = nullptr;     // its velocity's or factor's y; a check's y1; a noise's z
        const StateVector* request2 = nullptr;    // err of a check (null: none)
        RPYBackend::TryCheck check{0.0, -1};      // the check's result
        StateVector* reply = nullptr;             // where the velocity goes
        std::exception_ptr jobError;              // the job's failure, rethrown in the fiber
        std::string faultKind, faultMessage;
        ucontext_t fiber;
        std::unique_ptr<char[]> stack;
        bool placed = false;  // positions and time given (or taken from the Context)
    };
    Copy& copyAt(int k) { return *copies[k]; }
    const Copy& copyAt(int k) const { return *copies[k]; }

    int n = 0;                        // beads per copy
    int threads = 1;                  // the integrator's, over the copies (shareOut)
    std::vector<int> beadParticle;    // bead (all copies) -> particle
    bool hasVirtualSites = false;
    bool apart = true;                // copies on a grid (else each at its centre of mass)
    std::string forceError;           // the last evaluation's failure, "" when it succeeded

private:
    static void fiberEntry(int low, int high);
    void runCopy(Copy& c);
    void wait(Copy& c, State state, const StateVector& y, StateVector* v);
    std::unique_ptr<OpenMM::ThreadPool> pool;  // shareOut's, made at its first jobs
#ifdef __linux__
    cpu_set_t cores;                  // the process's cores when the batch was made
#endif
    double margin = 1.0;              // nm: twice the largest nonbonded cutoff
    double gridSpacing = 0.0;         // nm: 0 until the first evaluation sets it
    int gridSide = 1;
    std::vector<std::unique_ptr<Copy>> copies;
    ucontext_t scheduler;
    Copy* running = nullptr;
    OpenMM::ContextImpl* context = nullptr;
    std::chrono::steady_clock::time_point start;
    double budget = 0.0;
};

/**
 * A copy's backend: the platform's backend `Base` (its vectors, noise and mobility for the
 * copy's n beads) whose positions live in the batch and whose velocity waits for the batch.
 */
template <class Base>
class BatchedBackend : public Base {
public:
    template <class... Args>
    BatchedBackend(CopyBatch& batch, int index, Args&&... args)
        : Base(std::forward<Args>(args)...), batch(batch), index(index) {}
    void getPositions(OpenMM::ContextImpl&, StateVector& y) override { this->copy(y, batch.positionsOf(index)); }
    void setPositions(OpenMM::ContextImpl&, const StateVector& y) override { this->copy(batch.positionsOf(index), y); }
    bool holds(OpenMM::ContextImpl&, const StateVector& y) override { return this->equal(y, batch.positionsOf(index)); }
    void velocity(OpenMM::ContextImpl&, const StateVector& y, StateVector& v) override {
        batch.waitForVelocity(index, y, v);
    }
    void groupEnergies(OpenMM::ContextImpl&, const StateVector&, const std::vector<int>&,
                       std::vector<double>&) override {
        throw OpenMM::OpenMMException("RPYIntegrator: the energies of one copy of a batch are not available; "
                                      "evaluate them on a Context of that copy alone");
    }

protected:
    CopyBatch& batch;
    int index;
};

} // namespace KnotMM

#endif
