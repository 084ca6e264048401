#include "knotmm/stepper/Stepper.h"

#include "knotmm/RPYStepFault.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

using namespace OpenMM;
using namespace KnotMM;

Stepper::Stepper(RPYBackend& backend, const RPYIntegrator& integrator)
    : work(backend, rpyMethodInfo(integrator.getMethod()).id), fixed(backend), rk23(backend),
      rkc2(backend, integrator.getSpectralRadiusStartVector()), brownian(backend) {
    const int seed = integrator.getRandomNumberSeed();
    // 0: a fresh stream each time, as OpenMM's own integrators
    work.noise.seed(seed != 0 ? (uint64_t) (uint32_t) seed
                              : (uint64_t) std::random_device()() << 32 ^ std::random_device()());
    work.kT = integrator.getThermalEnergy();
}

void Stepper::invalidateCache() {
    work.k1.valid = false;
    rkc2.forgetSpectralRadius();  // as knotmm's RKC2.reset(): estimate again after outside changes
}

void Stepper::syncState(ContextImpl& context, const RPYIntegrator& integrator) {
    RPYBackend& b = work.backend;
    StateVector& y = *work.y;
    const long long version = integrator.getPositionsVersion();
    if (!haveState) {
        // the first step, or a checkpoint of a layout without the state (versions 2-4): the
        // Context's positions; the caches of such a checkpoint hold while they are exactly
        // those they were computed at (as those layouts were written to continue)
        b.getPositions(context, y);
        if (work.k1.valid && !b.equal(y, *work.k1.positions))
            invalidateCache();
        if (fixed.held.valid && !b.equal(y, *fixed.held.positions))
            fixed.held.valid = false;  // moved from outside: as knotmm's LeimkuhlerMatthews.reset()
        haveState = true;
    }
    else if ((version != seenVersion || checkPositions) && !b.holds(context, y)) {
        // set from outside to other positions: start from them, as knotmm's engines do
        b.getPositions(context, y);
        invalidateCache();
        fixed.held.valid = false;
    }
    // (set from outside to the positions the stepper wrote, as knotmm's engine does between
    // calls, and Context.loadCheckpoint: the state and the caches go on)
    seenVersion = version;
    checkPositions = false;
}

void Stepper::groupEnergies(ContextImpl& context, const RPYIntegrator& integrator, const std::vector<int>& groups,
                            std::vector<double>& energies) {
    syncState(context, integrator);
    work.backend.groupEnergies(context, *work.y, groups, energies);
}

double Stepper::estimateSpectralRadius(ContextImpl& context, RPYIntegrator& integrator) {
    // A fresh RKC2Control (its start vector, no earlier estimate), at the state's positions;
    // the counters, the cached velocity and the Context's positions are restored.
    RPYBackend& b = work.backend;
    work.context = &context;
    work.integrator = &integrator;
    b.applySettings(integrator);
    const StepCounts counted = work.counts;
    syncState(context, integrator);
    RKC2Control probe(b, integrator.getSpectralRadiusStartVector());
    VectorPtr f0 = b.createVector();
    double rho;
    try {
        work.velocity(*work.y, *f0);
        rho = probe.estimate(work, *f0);
    }
    catch (...) {
        b.setPositions(context, *work.y);
        work.counts = counted;
        throw;
    }
    b.setPositions(context, *work.y);
    work.counts = counted;
    return rho;
}

double Stepper::step(ContextImpl& context, RPYIntegrator& integrator, double targetTime) {
    const double t0 = context.getTime();
    const double h = advance(context, integrator, t0, targetTime);
    double t1 = t0 + h;
    if (std::isfinite(targetTime) && std::fabs(targetTime - t1) <= landingSlack(targetTime))
        t1 = targetTime;  // land exactly
    context.setTime(t1);
    context.setStepCount(context.getStepCount() + 1);
    return h;
}

double Stepper::advance(ContextImpl& context, RPYIntegrator& integrator, double t0, double targetTime) {
    RPYBackend& b = work.backend;
    work.context = &context;
    work.integrator = &integrator;
    work.t0 = t0;
    work.kT = integrator.getThermalEnergy();
    b.applySettings(integrator);
    syncState(context, integrator);
    StateVector& y = *work.y;
    // The cached velocity is valid while the parameters are those it was computed at (the
    // positions: syncState).
    if (work.k1.valid && context.getParameters() != work.k1.parameters)
        invalidateCache();
    const double maxDt = std::isfinite(targetTime) ? targetTime - t0 : std::numeric_limits<double>::infinity();
    double h;
    work.y1NonFinite = -2;
    try {
        if (work.method == RPYMethod::RK23)
            h = rk23.step(work, maxDt);
        else if (work.method == RPYMethod::RKC2)
            h = rkc2.step(work, maxDt);
        else if (work.method == RPYMethod::ItoHeunAdaptive)
            h = brownian.step(work, maxDt);
        else
            h = fixed.step(work, std::min(integrator.getStepSize(), maxDt));
        // an adaptive method checked its last try's y1 with the error estimate (one download)
        const int bad = work.y1NonFinite != -2 ? work.y1NonFinite : b.firstNonFinite(*work.y1);
        if (bad >= 0)
            throw RPYStepFault(RPYStepFault::NonFinite,
                               std::string("RPYIntegrator (") + work.name() +
                                   "): positions became non-finite at t = " + formatNumber(t0 + h) + " ps (bead " +
                                   std::to_string(bad / 3) +
                                   "); the last good state is kept. Lower the step size or the error tolerance",
                               work.name(), t0, bad / 3);
    }
    catch (const RPYStepFault& fault) {
        b.setPositions(context, y);
        work.k1.valid = false;
        fixed.held.valid = false;
        throw fault.at(work.name(), t0);
    }
    catch (...) {
        b.setPositions(context, y);
        work.k1.valid = false;
        fixed.held.valid = false;
        throw;
    }
    b.setPositions(context, *work.y1);
    if (fixed.held.valid)
        b.copy(*fixed.held.positions, *work.y1);
    work.y.swap(work.y1);  // the new state
    work.counts.accepted++;
    return h;
}
