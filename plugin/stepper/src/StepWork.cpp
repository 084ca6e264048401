#include "knotmm/stepper/StepWork.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/internal/ContextImpl.h"

#include <cmath>
#include <limits>

using namespace KnotMM;

StepWork::StepWork(RPYBackend& backend, RPYMethod method)
    : backend(backend), method(method), y(backend.createVector()), y1(backend.createVector()),
      xi(backend.createVector()) {
    k1.v = backend.createVector();
    k1.positions = backend.createVector();
}

void StepWork::velocity(const StateVector& at, StateVector& v) {
    backend.velocity(*context, at, v);
    counts.evaluations++;
}

void StepWork::keepVelocity(const StateVector& at) {
    k1.valid = true;
    backend.copy(*k1.positions, at);
    const std::map<std::string, double>& now = context->getParameters();
    if (k1.parameters != now)  // compared first: a copy of equal maps would allocate every step
        k1.parameters = now;
}

void StepWork::noiseSample(const StateVector& at, double scale, StateVector& out) {
    if (scale == 0.0) {
        backend.setZero(out);
        return;
    }
    backend.factorNoise(at);
    backend.normals(noise, *xi);
    backend.applyNoise(scale, *xi, out);
}

void StepWork::reject(double next, double error, const char* tail) {
    counts.rejected++;
    integrator->setStepSize(next);
    if (next < integrator->getMinimumStepSize())
        throw RPYStepFault(RPYStepFault::StepUnderflow,
                           std::string("RPYIntegrator (") + name() + "): the step fell to " + formatNumber(next) +
                               " ps, below minimumStepSize, at t = " + formatNumber(t0) +
                               " ps (error estimate " + formatNumber(error) + " x tolerance)" + tail,
                           name(), t0, -1, error);
}

double StepWork::errorRatio(const StateVector& err, double tolerance) {
    const RPYBackend::TryCheck check = backend.checkTry(err, *y1);
    y1NonFinite = check.nonFinite;
    return std::isfinite(check.errorNorm) ? check.errorNorm / tolerance : std::numeric_limits<double>::infinity();
}
