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

double Stepper::estimateSpectralRadius(ContextImpl& context, RPYIntegrator& integrator) {
    // A fresh RKC2Control (its start vector, no earlier estimate), at the Context's
    // positions; the counters, the cached velocity and the Context's positions are restored.
    RPYBackend& b = work.backend;
    work.context = &context;
    work.integrator = &integrator;
    b.applySettings(integrator);
    const StepCounts counted = work.counts;
    b.getPositions(context, *work.y);
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
    StateVector& y = *work.y;
    b.getPositions(context, y);
    // The cached velocity is valid while positions and parameters are exactly those it was
    // computed at. (Checking them here, rather than trusting stateChanged(), keeps it across
    // Context.loadCheckpoint, which restores both and then reports them as changed.)
    if (work.k1.valid && (!b.equal(y, *work.k1.positions) || context.getParameters() != work.k1.parameters))
        invalidateCache();
    if (fixed.held.valid && !b.equal(y, *fixed.held.positions))
        fixed.held.valid = false;  // moved from outside: as knotmm's LeimkuhlerMatthews.reset()
    const double maxDt = std::isfinite(targetTime) ? targetTime - t0 : std::numeric_limits<double>::infinity();
    double h;
    try {
        if (work.method == RPYMethod::RK23)
            h = rk23.step(work, maxDt);
        else if (work.method == RPYMethod::RKC2)
            h = rkc2.step(work, maxDt);
        else if (work.method == RPYMethod::ItoHeunAdaptive)
            h = brownian.step(work, maxDt);
        else
            h = fixed.step(work, std::min(integrator.getStepSize(), maxDt));
        const int bad = b.firstNonFinite(*work.y1);
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
    work.counts.accepted++;
    return h;
}
