#include "knotmm/stepper/RK23.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <cmath>

using namespace KnotMM;

RK23Control::RK23Control(RPYBackend& backend)
    : k2(backend.createVector()), k3(backend.createVector()), k4(backend.createVector()),
      ytmp(backend.createVector()), err(backend.createVector()) {}

double RK23Control::step(StepWork& work, double maxDt) {
    // Bogacki-Shampine 3(2), FSAL, PI step control: knotmm.dynamics.deterministic.RK23.
    RPYBackend& b = work.backend;
    RPYIntegrator& integrator = *work.integrator;
    const StateVector& y = *work.y;
    StateVector& y1 = *work.y1;
    const double tol = integrator.getErrorTolerance();
    if (!work.k1.valid) {
        work.velocity(y, *work.k1.v);
        work.keepVelocity(y);
    }
    while (true) {
        const StateVector& k1 = *work.k1.v;
        const double hTry = integrator.getStepSize();
        const double h = std::min(hTry, maxDt);
        b.combine(*ytmp, {times(1.0, y), times(0.5 * h, k1)});
        work.velocity(*ytmp, *k2);
        b.combine(*ytmp, {times(1.0, y), times(0.75 * h, *k2)});
        work.velocity(*ytmp, *k3);
        // y1 = y + h (2 k1 + 3 k2 + 4 k3) / 9
        b.combine(*err, {times(2.0, k1), times(3.0, *k2), times(4.0, *k3)});
        b.combine(*err, {times(h, *err)});
        b.combine(y1, {times(1.0, y), over(*err, 9.0)});
        work.velocity(y1, *k4);
        // err = h (-5/72 k1 + k2/12 + k3/9 - k4/8)
        b.combine(*err, {times(-5.0 / 72.0, k1), over(*k2, 12.0), over(*k3, 9.0), over(*k4, -8.0)});
        b.combine(*err, {times(h, *err)});
        const double e = work.errorRatio(*err, tol);
        if (e <= 1.0) {
            double fac = 5.0;
            if (e != 0.0)
                fac = std::min(5.0, std::max(0.2, 0.9 * std::pow(e, -0.7 / 3.0) * std::pow(errOld, 0.4 / 3.0)));
            if (h >= hTry || fac < 1.0)  // a step clipped to land on the target keeps its size
                integrator.setStepSize(std::min(integrator.getMaximumStepSize(), h * fac));
            errOld = std::max(e, 1e-4);
            work.k1.v.swap(k4);
            work.keepVelocity(y1);
            return h;
        }
        const double fac = std::isfinite(e) ? std::max(0.2, 0.9 * std::pow(e, -1.0 / 3.0)) : 0.2;
        work.reject(h * fac, e, "; the forces are too stiff here. The last good state is kept");
    }
}
