#include "ReferenceRPYBatch.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYMethods.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/CustomNonbondedForce.h"
#include "openmm/NonbondedForce.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/ThreadPool.h"
#include "openmm/reference/ReferencePlatform.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <utility>
#ifdef __linux__
#include <sched.h>
#endif

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

namespace {

const size_t FIBER_STACK_BYTES = 1 << 20;  // reserved, touched only as used

ReferencePlatform::PlatformData& platformData(ContextImpl& context) {
    return *static_cast<ReferencePlatform::PlatformData*>(context.getPlatformData());
}

inline vector<double>& data(StateVector& v) { return static_cast<ReferenceVector&>(v).a; }
inline const vector<double>& data(const StateVector& v) { return static_cast<const ReferenceVector&>(v).a; }

/** The settings of `from` (all but the Context it is bound to), for a copy stepped alone. */
void copySettings(const RPYIntegrator& from, RPYIntegrator& to) {
    to.setErrorTolerance(from.getErrorTolerance());
    to.setBeadDiameter(from.getBeadDiameter());
    to.setMobility(from.getMobility());
    to.setThermalEnergy(from.getThermalEnergy());
    to.setNoiseMethod(from.getNoiseMethod());
    to.setLanczosTolerance(from.getLanczosTolerance());
    to.setMinimumStepSize(from.getMinimumStepSize());
    to.setMaximumStepSize(from.getMaximumStepSize());
    to.setNumThreads(from.getNumThreads());
    to.setIntegrationForceGroups(from.getIntegrationForceGroups());
}

} // namespace

// --- a copy's backend ----------------------------------------------------------------------------

void CopyBackend::getPositions(ContextImpl&, StateVector& y) { data(y) = batch.copies[copy]->positions; }

void CopyBackend::setPositions(ContextImpl&, const StateVector& y) { batch.copies[copy]->positions = data(y); }

bool CopyBackend::holds(ContextImpl&, const StateVector& y) { return data(y) == batch.copies[copy]->positions; }

void CopyBackend::velocity(ContextImpl&, const StateVector& y, StateVector& v) {
    ReferenceRPYBatch::Copy& c = *batch.copies[copy];
    batch.waitForForces(c, data(y));  // forces and mu F made by the batch
    data(v) = c.velocity;
}

void CopyBackend::factorNoise(const StateVector& y) {
    if (lanczosNoise() || batch.threads < 2) {
        // matrix-free, or no threads to share it out: factorised here, where the copy's
        // next steps use the factor while it is still in the cache
        ReferenceRPYBackend::factorNoise(y);
        return;
    }
    batch.waitForFactor(*batch.copies[copy], data(y));
}

void CopyBackend::factorJob(const vector<double>& y) {
    ReferenceVector at(3 * numBeads());
    at.a = y;
    ReferenceRPYBackend::factorNoise(at);
}

void CopyBackend::groupEnergies(ContextImpl&, const StateVector&, const vector<int>&, vector<double>&) {
    throw OpenMMException("RPYIntegrator: the energies of one copy of a batch are not available; "
                          "evaluate them on a Context of that copy alone");
}

// --- the batch -----------------------------------------------------------------------------------

ReferenceRPYBatch::ReferenceRPYBatch(const System& system, const RPYIntegrator& integrator) {
    const int count = integrator.getNumCopies();
    for (int i = 0; i < system.getNumParticles(); i++) {
        if (system.isVirtualSite(i))
            hasVirtualSites = true;
        else
            beadParticle.push_back(i);
    }
    if (beadParticle.size() % count != 0)
        throw OpenMMException("RPYIntegrator: " + std::to_string(beadParticle.size()) + " beads cannot be " +
                              std::to_string(count) + " copies of one system (numCopies must divide the beads)");
    n = (int) beadParticle.size() / count;
    double cutoff = 0.0;
    apart = integrator.getCopiesApart();
    for (int f = 0; f < system.getNumForces(); f++) {
        const Force& force = system.getForce(f);
        if (const NonbondedForce* nb = dynamic_cast<const NonbondedForce*>(&force)) {
            if (!apart)
                throw OpenMMException("RPYIntegrator: copies in one place (copiesApart = false) would all "
                                      "interact through a NonbondedForce; use a CustomNonbondedForce with "
                                      "one interaction group per copy, or keep the copies apart");
            if (nb->getNonbondedMethod() == NonbondedForce::NoCutoff)
                throw OpenMMException("RPYIntegrator: copies of a system need a cutoff on every nonbonded "
                                      "force (a NonbondedForce without one couples the copies)");
            cutoff = std::max(cutoff, nb->getCutoffDistance());
        }
        if (const CustomNonbondedForce* nb = dynamic_cast<const CustomNonbondedForce*>(&force)) {
            if (!apart) {
                if (nb->getNumInteractionGroups() < count)
                    throw OpenMMException("RPYIntegrator: copies in one place (copiesApart = false) need one "
                                          "interaction group per copy in every CustomNonbondedForce");
                continue;
            }
            if (nb->getNonbondedMethod() == CustomNonbondedForce::NoCutoff)
                throw OpenMMException("RPYIntegrator: copies of a system need a cutoff on every nonbonded "
                                      "force (a CustomNonbondedForce without one couples the copies)");
            cutoff = std::max(cutoff, nb->getCutoffDistance());
        }
    }
    margin = std::max(1.0, 2.0 * cutoff);
    threads = integrator.getNumThreads();
#ifdef __linux__
    CPU_ZERO(&cores);
    if (sched_getaffinity(0, sizeof(cores), &cores) != 0)
        CPU_ZERO(&cores);
#endif
    while (gridSide * gridSide * gridSide < count)
        gridSide++;
    const vector<Vec3>& start = integrator.getSpectralRadiusStartVector();
    const RPYMethodInfo& method = rpyMethodInfo(integrator.getMethod());
    for (int k = 0; k < count; k++) {
        std::unique_ptr<Copy> c(new Copy());
        c->settings.reset(new RPYIntegrator(integrator.getStepSize(), method.name, integrator.getErrorTolerance()));
        copySettings(integrator, *c->settings);
        c->settings->setNumThreads(1);
        c->settings->setRandomNumberSeed(integrator.getRandomNumberSeed());
        if (!start.empty())
            c->settings->setSpectralRadiusStartVector(vector<Vec3>(start.begin() + k * n, start.begin() + (k + 1) * n));
        c->backend.reset(new CopyBackend(*this, k, n, *c->settings));
        c->stepper.reset(new Stepper(*c->backend, *c->settings));
        c->positions.assign(3 * n, 0.0);
        c->forces.assign(n, Vec3());
        c->velocity.assign(3 * n, 0.0);
        c->stack.reset(new char[FIBER_STACK_BYTES]);
        copies.push_back(std::move(c));
    }
}

ReferenceRPYBatch::~ReferenceRPYBatch() {}

void ReferenceRPYBatch::setPositions(int copy, const vector<double>& positions) {
    copies[copy]->positions = positions;
    copies[copy]->placed = true;
    copies[copy]->stepper->positionsChanged();
}

void ReferenceRPYBatch::createCheckpoint(int copy, std::ostream& stream) const {
    const Copy& c = *copies[copy];
    RPYIntegrator::writeStateHeader(stream, c.settings->getStepSize());
    c.stepper->createCheckpoint(stream);
}

void ReferenceRPYBatch::loadCheckpoint(int copy, std::istream& stream) {
    Copy& c = *copies[copy];
    c.settings->setStepSize(RPYIntegrator::readStateHeader(stream));
    c.stepper->loadCheckpoint(stream);
}

void ReferenceRPYBatch::clearFault(int copy) {
    copies[copy]->faultKind.clear();
    copies[copy]->faultMessage.clear();
}

void ReferenceRPYBatch::fiberEntry(int low, int high) {
    const uintptr_t address = (uintptr_t) (uint32_t) low | ((uintptr_t) (uint32_t) high << 32);
    ReferenceRPYBatch* batch = reinterpret_cast<ReferenceRPYBatch*>(address);
    batch->runCopy(*batch->running);
}  // returns to the scheduler (uc_link)

void ReferenceRPYBatch::runCopy(Copy& c) {
    // Every exception ends here: none may leave the fiber.
    try {
        while (c.time < c.target - landingSlack(c.target)) {
            const double h = c.stepper->advance(*context, *c.settings, c.time, c.target);
            double t1 = c.time + h;
            if (std::fabs(c.target - t1) <= landingSlack(c.target))
                t1 = c.target;  // land exactly
            c.time = t1;
            const std::chrono::duration<double> spent = std::chrono::steady_clock::now() - start;
            if (spent.count() >= budget)
                break;
        }
    }
    catch (const RPYStepFault& fault) {
        c.faultKind = fault.kindName();
        c.faultMessage = fault.what();
    }
    catch (const std::exception& error) {
        c.faultKind = "error";
        c.faultMessage = error.what();
    }
    catch (...) {
        c.faultKind = "error";
        c.faultMessage = "RPYIntegrator: a copy's step failed with an unknown exception";
    }
    c.state = State::Done;
}

void ReferenceRPYBatch::waitForForces(Copy& c, const vector<double>& y) {
    c.request = &y;
    c.state = State::WaitingForForces;
    swapcontext(&c.fiber, &scheduler);
    c.request = nullptr;
    if (!forceError.empty())
        throw OpenMMException(forceError);
    if (c.jobError)
        std::rethrow_exception(std::exchange(c.jobError, nullptr));
}

void ReferenceRPYBatch::waitForFactor(Copy& c, const vector<double>& y) {
    c.request = &y;
    c.state = State::WaitingForFactor;
    swapcontext(&c.fiber, &scheduler);
    c.request = nullptr;
    if (c.jobError)
        std::rethrow_exception(std::exchange(c.jobError, nullptr));
}

void ReferenceRPYBatch::startThreads() {
    // Made at the first jobs, after the Context: a caller that keeps OpenMM's CPU-platform
    // thread on its own core (knotmm's CorePin) does not count these among OpenMM's; each
    // takes the cores the process had when the batch was made, whatever its creator's.
    pool.reset(new ThreadPool(threads));
#ifdef __linux__
    if (CPU_COUNT(&cores) > 0) {
        pool->execute([&](ThreadPool&, int) { sched_setaffinity(0, sizeof(cores), &cores); });
        pool->waitForThreads();
    }
#endif
}

void ReferenceRPYBatch::runJobs() {
    vector<Copy*> jobs;
    for (auto& copy : copies)
        if ((copy->state == State::WaitingForForces && forceError.empty()) || copy->state == State::WaitingForFactor)
            jobs.push_back(copy.get());
    auto work = [&](Copy& c) {
        try {
            if (c.state == State::WaitingForForces)
                c.backend->velocityJob(*c.request, c.forces, c.velocity);
            else
                c.backend->factorJob(*c.request);
        }
        catch (...) {
            c.jobError = std::current_exception();
        }
    };
    if (threads > 1 && !pool && jobs.size() > 1)
        startThreads();
    if (!pool || jobs.size() < 2) {
        for (Copy* c : jobs)
            work(*c);
        return;
    }
    std::atomic<size_t> next(0);
    pool->execute([&](ThreadPool&, int) {
        for (size_t j = next++; j < jobs.size(); j = next++)
            work(*jobs[j]);
    });
    pool->waitForThreads();
}

void ReferenceRPYBatch::evaluateForces(ContextImpl& context) {
    // Each copy at its own grid point: its beads shifted to their centre of mass (as one system
    // alone is evaluated), then moved to the point. The points are farther apart than any two
    // copies reach plus twice the cutoff.
    const int count = numCopies();
    vector<const vector<double>*> at(count);
    vector<Vec3> centre(count);
    double reach = 0.0;
    for (int j = 0; j < count; j++) {
        const Copy& c = *copies[j];
        at[j] = c.state == State::WaitingForForces ? c.request : &c.positions;
        const vector<double>& y = *at[j];
        double com[3] = {0.0, 0.0, 0.0};
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                com[k] += y[3 * b + k];
        for (int k = 0; k < 3; k++)
            com[k] /= n;
        centre[j] = Vec3(com[0], com[1], com[2]);
        for (int b = 0; b < n; b++) {
            const double dx = y[3 * b] - com[0], dy = y[3 * b + 1] - com[1], dz = y[3 * b + 2] - com[2];
            reach = std::max(reach, std::sqrt(dx * dx + dy * dy + dz * dz));
        }
    }
    if (!std::isfinite(reach))
        reach = 0.0;  // a copy with non-finite positions fails on its own; the others stay apart
    // The spacing is a function of the copies' reach alone, on a ladder of powers of two:
    // where a copy sits (and so how its forces round) does not depend on the history of the
    // batch, only on the bracket of the widest copy now; a resumed batch places it alike.
    double rung = 1.0;
    while (rung < reach)
        rung *= 2.0;
    gridSpacing = apart ? 2.0 * rung + margin : 0.0;
    vector<Vec3>& pos = *platformData(context).positions;
    const double middle = 0.5 * (gridSide - 1);
    for (int j = 0; j < count; j++) {
        const double off[3] = {(j % gridSide - middle) * gridSpacing, ((j / gridSide) % gridSide - middle) * gridSpacing,
                               (j / (gridSide * gridSide) - middle) * gridSpacing};
        const vector<double>& y = *at[j];
        for (int b = 0; b < n; b++)
            pos[beadParticle[j * n + b]] = Vec3((y[3 * b] - centre[j][0]) + off[0], (y[3 * b + 1] - centre[j][1]) + off[1],
                                                (y[3 * b + 2] - centre[j][2]) + off[2]);
    }
    forceError.clear();
    try {
        if (hasVirtualSites)
            context.computeVirtualSites();
        context.calcForcesAndEnergy(true, false, context.getIntegrator().getIntegrationForceGroups());
    }
    catch (const std::exception& error) {
        forceError = error.what();
        if (forceError.empty())
            forceError = "RPYIntegrator: the force evaluation failed";
        return;
    }
    const vector<Vec3>& force = *platformData(context).forces;
    for (int j = 0; j < count; j++) {
        Copy& c = *copies[j];
        if (c.state != State::WaitingForForces)
            continue;
        for (int b = 0; b < n; b++)
            c.forces[b] = force[beadParticle[j * n + b]];
    }
}

bool ReferenceRPYBatch::stepTo(ContextImpl& contextRef, RPYIntegrator& integrator, const vector<double>& targets,
                               double maxSeconds) {
    context = &contextRef;
    start = std::chrono::steady_clock::now();
    budget = maxSeconds;
    const vector<Vec3>& contextPositions = *platformData(contextRef).positions;
    const uintptr_t address = reinterpret_cast<uintptr_t>(this);
    for (int k = 0; k < numCopies(); k++) {
        Copy& c = *copies[k];
        if (!c.placed) {  // never given positions: the Context's, as it was created
            for (int b = 0; b < n; b++)
                for (int i = 0; i < 3; i++)
                    c.positions[3 * b + i] = contextPositions[beadParticle[k * n + b]][i];
            c.time = contextRef.getTime();
            c.placed = true;
            c.stepper->positionsChanged();
        }
        const double h = c.settings->getStepSize();
        copySettings(integrator, *c.settings);
        c.settings->setNumThreads(1);  // the batch's threads share out the copies instead
        c.settings->setStepSize(h);
        c.target = targets[k];
        c.state = State::Idle;
        if (!c.faultKind.empty() || !(c.time < c.target - landingSlack(c.target)))
            continue;
        getcontext(&c.fiber);
        c.fiber.uc_stack.ss_sp = c.stack.get();
        c.fiber.uc_stack.ss_size = FIBER_STACK_BYTES;
        c.fiber.uc_link = &scheduler;
        makecontext(&c.fiber, (void (*)()) fiberEntry, 2, (int) (uint32_t) address, (int) (uint32_t) (address >> 32));
        c.state = State::Runnable;
    }
    while (true) {
        for (auto& copy : copies) {
            Copy& c = *copy;
            if (c.state != State::Runnable)
                continue;
            running = &c;
            swapcontext(&scheduler, &c.fiber);  // back when it waits for forces or is done
            running = nullptr;
        }
        bool forces = false, factors = false;
        for (auto& copy : copies) {
            forces = forces || copy->state == State::WaitingForForces;
            factors = factors || copy->state == State::WaitingForFactor;
        }
        if (!forces && !factors)
            break;
        if (forces)
            evaluateForces(contextRef);
        runJobs();
        for (auto& copy : copies)
            if (copy->state == State::WaitingForForces || copy->state == State::WaitingForFactor)
                copy->state = State::Runnable;
    }
    bool reached = true;
    for (auto& copy : copies)
        if (copy->faultKind.empty() && copy->time < copy->target - landingSlack(copy->target))
            reached = false;
    return reached;
}
