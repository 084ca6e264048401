#include "knotmm/stepper/AdaptiveBrownian.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <cmath>

using namespace KnotMM;

namespace {
const double ERROR_ORDER = 1.5;  // the error estimate's order in h (noise dominated)

} // namespace

WienerQueue::WienerQueue(RPYBackend& backend)
    : backend(backend), xi(backend.createVector()), first(backend.createVector()) {}

void WienerQueue::take(StepWork& work, double h, StateVector& total) {
    backend.setZero(total);
    double need = h;
    while (need > 0.0) {
        if (pending.empty()) {
            backend.normals(work.noise, *xi);
            backend.combine(total, {times(1.0, total), times(std::sqrt(need), *xi)});
            return;
        }
        const double span = pending.front().first;
        StateVector& dw = *pending.front().second;
        if (span <= need * (1.0 + 1e-12)) {  // the whole interval (to rounding) fits
            backend.combine(total, {times(1.0, total), times(1.0, dw)});
            need = span >= need * (1.0 - 1e-12) ? 0.0 : need - span;
            spare.push_back(std::move(pending.front().second));
            pending.pop_front();
            continue;
        }
        // the bridge: the value at `need` of a path that reaches dw at `span`
        backend.normals(work.noise, *xi);
        backend.combine(*first, {times(need / span, dw), times(std::sqrt(need * (span - need) / span), *xi)});
        backend.combine(dw, {times(1.0, dw), times(-1.0, *first)});
        pending.front().first = span - need;
        backend.combine(total, {times(1.0, total), times(1.0, *first)});
        return;
    }
}

void WienerQueue::giveBack(double h, const StateVector& dw) {
    VectorPtr copy;
    if (spare.empty())
        copy = backend.createVector();
    else {
        copy = std::move(spare.back());
        spare.pop_back();
    }
    backend.copy(*copy, dw);
    pending.emplace_front(h, std::move(copy));
}

AdaptiveBrownian::AdaptiveBrownian(RPYBackend& backend)
    : queue(backend), dw(backend.createVector()), w(backend.createVector()), yEuler(backend.createVector()),
      v1(backend.createVector()), diff(backend.createVector()), err(backend.createVector()) {}

double AdaptiveBrownian::step(StepWork& work, double maxDt) {
    RPYBackend& b = work.backend;
    RPYIntegrator& integrator = *work.integrator;
    const StateVector& y = *work.y;
    StateVector& y1 = *work.y1;
    StateVector& v0 = *work.k1.v;
    const double tol = integrator.getErrorTolerance();
    const bool noisy = work.kT > 0.0;
    work.velocity(y, v0);
    bool factored = false;
    while (true) {
        const double hTry = integrator.getStepSize();
        const double h = std::min(hTry, maxDt);
        if (noisy) {
            queue.take(work, h, *dw);
            if (!factored) {
                b.factorNoise(y);  // B(y) once for every retry from y
                factored = true;
            }
            b.applyNoise(std::sqrt(2.0 * work.kT), *dw, *w);
        }
        else
            b.setZero(*w);
        b.combine(*yEuler, {times(1.0, y), times(h, v0), times(1.0, *w)});
        work.velocity(*yEuler, *v1);
        b.combine(*diff, {times(1.0, v0), times(1.0, *v1)});
        b.combine(y1, {times(1.0, y), times(0.5 * h, *diff), times(1.0, *w)});
        b.combine(*diff, {times(1.0, *v1), times(-1.0, v0)});
        b.combine(*err, {times(0.5 * h, *diff)});
        const double e = work.errorRatio(*err, tol);
        if (e <= 1.0) {
            double fac = 5.0;
            if (e != 0.0)
                fac = std::min(5.0, std::max(0.2, 0.9 * std::pow(e, -0.7 / ERROR_ORDER) *
                                                      std::pow(errOld, 0.4 / ERROR_ORDER)));
            if (h >= hTry || fac < 1.0)  // a step clipped to land on the target keeps its size
                integrator.setStepSize(std::min(integrator.getMaximumStepSize(), h * fac));
            errOld = std::max(e, 1e-4);
            return h;
        }
        if (noisy)
            queue.giveBack(h, *dw);
        const double fac = std::isfinite(e) ? std::max(0.1, 0.9 * std::pow(e, -1.0 / ERROR_ORDER)) : 0.1;
        work.reject(h * fac, e, ". The last good state is kept");
    }
}
