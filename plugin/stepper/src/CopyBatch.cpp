#include "knotmm/stepper/CopyBatch.h"

#include "knotmm/RPYMethods.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/CustomNonbondedForce.h"
#include "openmm/NonbondedForce.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/internal/ThreadPool.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

namespace {

const size_t FIBER_STACK_BYTES = 1 << 20;  // reserved, touched only as used

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

CopyBatch::CopyBatch(const System& system, const RPYIntegrator& integrator) {
    const int count = integrator.getNumCopies();
    threads = integrator.getNumThreads();
#ifdef __linux__
    CPU_ZERO(&cores);
    if (sched_getaffinity(0, sizeof(cores), &cores) != 0)
        CPU_ZERO(&cores);
#endif
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
    while (gridSide * gridSide * gridSide < count)
        gridSide++;
}

CopyBatch::~CopyBatch() {}

void CopyBatch::shareOut(const vector<int>& jobs, const std::function<void(int)>& work) {
    if (threads < 2 || jobs.size() < 2) {
        for (int k : jobs)
            work(k);
        return;
    }
    if (!pool) {
        // Made at the first jobs, after the Context: a caller that keeps OpenMM's CPU-platform
        // thread on its own core (knotmm's CorePin) does not count these among OpenMM's
        pool.reset(new ThreadPool(threads));
#ifdef __linux__
        if (CPU_COUNT(&cores) > 0) {
            pool->execute([&](ThreadPool&, int) { sched_setaffinity(0, sizeof(cores), &cores); });
            pool->waitForThreads();
        }
#endif
    }
    std::atomic<size_t> next(0);
    pool->execute([&](ThreadPool&, int) {
        for (size_t j = next++; j < jobs.size(); j = next++)
            work(jobs[j]);
    });
    pool->waitForThreads();
}

void CopyBatch::createCopies(const RPYIntegrator& integrator) {
    const int count = integrator.getNumCopies();
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
        copies.push_back(std::move(c));
        Copy& made = *copies.back();
        made.backend = makeBackend(k, *made.settings);
        made.stepper.reset(new Stepper(*made.backend, *made.settings));
        made.positions = made.backend->createVector();
        made.stack.reset(new char[FIBER_STACK_BYTES]);
    }
}

vector<double> CopyBatch::getPositions(int copy) const {
    const Copy& c = *copies[copy];
    vector<double> out;
    c.backend->download(*c.positions, out);
    return out;
}

void CopyBatch::setPositions(int copy, const vector<double>& positions) {
    Copy& c = *copies[copy];
    c.backend->upload(positions, *c.positions);
    c.placed = true;
    c.stepper->positionsChanged();
}

void CopyBatch::createCheckpoint(int copy, std::ostream& stream) const {
    const Copy& c = *copies[copy];
    RPYIntegrator::writeStateHeader(stream, c.settings->getStepSize());
    c.stepper->createCheckpoint(stream);
}

void CopyBatch::loadCheckpoint(int copy, std::istream& stream) {
    Copy& c = *copies[copy];
    c.settings->setStepSize(RPYIntegrator::readStateHeader(stream));
    c.stepper->loadCheckpoint(stream);
}

void CopyBatch::clearFault(int copy) {
    copies[copy]->faultKind.clear();
    copies[copy]->faultMessage.clear();
}

double CopyBatch::placeCopies(double reach) {
    if (!std::isfinite(reach))
        reach = 0.0;  // a copy with non-finite positions fails on its own; the others stay apart
    // The spacing is a function of the copies' reach alone, on a ladder of powers of two:
    // where a copy sits (and so how its forces round) does not depend on the history of the
    // batch, only on the bracket of the widest copy now; a resumed batch places it alike.
    double rung = 1.0;
    while (rung < reach)
        rung *= 2.0;
    gridSpacing = apart ? 2.0 * rung + margin : 0.0;
    return gridSpacing;
}

void CopyBatch::gridOffset(int j, double off[3]) const {
    const double middle = 0.5 * (gridSide - 1);
    off[0] = (j % gridSide - middle) * gridSpacing;
    off[1] = ((j / gridSide) % gridSide - middle) * gridSpacing;
    off[2] = (j / (gridSide * gridSide) - middle) * gridSpacing;
}

bool CopyBatch::calcForces(ContextImpl& context, const std::function<void()>& placeSites) {
    try {
        if (hasVirtualSites)
            placeSites();
        context.calcForcesAndEnergy(true, false, context.getIntegrator().getIntegrationForceGroups());
    }
    catch (const std::exception& error) {
        forceError = error.what();
        if (forceError.empty())
            forceError = "RPYIntegrator: the force evaluation failed";
        return false;
    }
    return true;
}

void CopyBatch::fiberEntry(int low, int high) {
    const uintptr_t address = (uintptr_t) (uint32_t) low | ((uintptr_t) (uint32_t) high << 32);
    CopyBatch* batch = reinterpret_cast<CopyBatch*>(address);
    batch->runCopy(*batch->running);
}  // returns to the scheduler (uc_link)

void CopyBatch::runCopy(Copy& c) {
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

void CopyBatch::wait(Copy& c, State state, const StateVector& y, StateVector* v) {
    c.request = &y;
    c.reply = v;
    c.state = state;
    swapcontext(&c.fiber, &scheduler);
    c.request = nullptr;
    c.reply = nullptr;
    if (state == State::WaitingForVelocity && !forceError.empty())
        throw OpenMMException(forceError);
    if (c.jobError)
        std::rethrow_exception(std::exchange(c.jobError, nullptr));
}

void CopyBatch::waitForVelocity(int copy, const StateVector& y, StateVector& v) {
    wait(*copies[copy], State::WaitingForVelocity, y, &v);
}

void CopyBatch::waitForFactor(int copy, const StateVector& y) {
    wait(*copies[copy], State::WaitingForFactor, y, nullptr);
}

RPYBackend::TryCheck CopyBatch::waitForCheck(int copy, const StateVector* err, const StateVector& y1) {
    Copy& c = *copies[copy];
    c.request2 = err;
    wait(c, State::WaitingForCheck, y1, nullptr);
    c.request2 = nullptr;
    return c.check;
}

void CopyBatch::waitForNoise(int copy, const StateVector& z, StateVector& out) {
    wait(*copies[copy], State::WaitingForNoise, z, &out);
}

void CopyBatch::waitForSettle(int copy) {
    Copy& c = *copies[copy];
    c.request = nullptr;
    c.reply = nullptr;
    c.state = State::WaitingToSettle;
    swapcontext(&c.fiber, &scheduler);
    if (c.jobError)
        std::rethrow_exception(std::exchange(c.jobError, nullptr));
}


bool CopyBatch::stepTo(ContextImpl& contextRef, RPYIntegrator& integrator, const vector<double>& targets,
                       double maxSeconds) {
    context = &contextRef;
    start = std::chrono::steady_clock::now();
    budget = maxSeconds;
    const uintptr_t address = reinterpret_cast<uintptr_t>(this);
    for (int k = 0; k < numCopies(); k++) {
        Copy& c = *copies[k];
        if (!c.placed) {  // never given positions: the Context's, as it was created
            readContextPositions(contextRef, k, *c.positions);
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
            swapcontext(&scheduler, &c.fiber);  // back when it waits or is done
            running = nullptr;
        }
        bool velocities = false, waiting = false;
        for (auto& copy : copies) {
            velocities = velocities || copy->state == State::WaitingForVelocity;
            waiting = waiting || (copy->state != State::Done && copy->state != State::Idle);
        }
        if (!waiting)
            break;
        forceError.clear();
        settle();
        if (velocities)
            evaluate(contextRef);
        runJobs();
        for (auto& copy : copies)
            if (copy->state != State::Done && copy->state != State::Idle)
                copy->state = State::Runnable;
    }
    settle();  // what the copies deferred last
    bool reached = true;
    for (auto& copy : copies)
        if (copy->faultKind.empty() && copy->time < copy->target - landingSlack(copy->target))
            reached = false;
    return reached;
}
