#include "knotmm/stepper/RKC2.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <cmath>

using namespace KnotMM;

namespace {
const int MAX_STAGES = 200;
const int RHO_INTERVAL = 25;  // steps between spectral-radius estimates
} // namespace

ChebyshevCoefficients KnotMM::chebyshevCoefficients(int s) {
    const double w0 = 1.0 + (2.0 / 13.0) / (s * s);
    std::vector<double> t(s + 1, 0.0), dt(s + 1, 0.0), ddt(s + 1, 0.0);
    t[0] = 1.0;
    t[1] = w0;
    dt[1] = 1.0;
    for (int j = 2; j <= s; j++) {
        t[j] = 2.0 * w0 * t[j - 1] - t[j - 2];
        dt[j] = 2.0 * t[j - 1] + 2.0 * w0 * dt[j - 1] - dt[j - 2];
        ddt[j] = 4.0 * dt[j - 1] + 2.0 * w0 * ddt[j - 1] - ddt[j - 2];
    }
    const double w1 = dt[s] / ddt[s];
    std::vector<double> b(s + 1, 0.0), a(s + 1, 0.0);
    for (int j = 2; j <= s; j++)
        b[j] = ddt[j] / (dt[j] * dt[j]);
    b[0] = b[1] = b[2];
    for (int j = 0; j <= s; j++)
        a[j] = 1.0 - b[j] * t[j];
    ChebyshevCoefficients c;
    c.mu.assign(s + 1, 0.0);
    c.nu.assign(s + 1, 0.0);
    c.muT.assign(s + 1, 0.0);
    c.gammaT.assign(s + 1, 0.0);
    c.muT[1] = b[1] * w1;
    for (int j = 2; j <= s; j++) {
        c.mu[j] = 2.0 * w0 * b[j] / b[j - 1];
        c.nu[j] = -b[j] / b[j - 2];
        c.muT[j] = 2.0 * w1 * b[j] / b[j - 1];
        c.gammaT[j] = -a[j - 1] * c.muT[j];
    }
    return c;
}

RKC2Control::RKC2Control(RPYBackend& backend, const std::vector<OpenMM::Vec3>& start)
    : eig(backend.createVector()), start(start), k2(backend.createVector()), k4(backend.createVector()),
      ytmp(backend.createVector()), err(backend.createVector()), sum(backend.createVector()),
      prev(backend.createVector()), prev2(backend.createVector()), probe(backend.createVector()),
      dv(backend.createVector()), v(backend.createVector()) {}

const ChebyshevCoefficients& RKC2Control::chebyshev(int s) {
    auto found = cache.find(s);
    if (found != cache.end())
        return found->second;
    return cache[s] = chebyshevCoefficients(s);
}

double RKC2Control::spectralRadius(StepWork& work, const StateVector& f0) {
    // Nonlinear power iteration on finite differences of v (knotmm's RKC2.spectral_radius).
    RPYBackend& b = work.backend;
    const StateVector& y = *work.y;
    const int n = b.numBeads(), m = 3 * n;
    const double size = 1e-3 * std::sqrt((double) m);
    if (haveEig)
        b.copy(*v, *eig);
    else {
        std::vector<double> host(m);
        if (!start.empty()) {
            for (int i = 0; i < n; i++)
                for (int k = 0; k < 3; k++)
                    host[3 * i + k] = start[i][k];
        }
        else {
            NoiseStream fixed;  // the same vector every time, independent of the run's noise
            fixed.seedSequential(12345);
            fixed.fill(host.data(), m);
        }
        b.upload(host, *v);
    }
    b.combine(*v, {times(size / std::max(b.norm(*v), 1e-300), *v)});
    double sigma = 0.0;
    for (int it = 0; it < 30; it++) {
        b.combine(*probe, {times(1.0, y), times(1.0, *v)});
        work.velocity(*probe, *dv);
        b.combine(*dv, {times(1.0, *dv), times(-1.0, f0)});
        const double dn = b.norm(*dv);
        if (!std::isfinite(dn) || dn == 0.0)
            break;
        const double sigmaNew = dn / size;
        b.combine(*v, {times(size / dn, *dv)});
        if (std::fabs(sigmaNew - sigma) <= 0.01 * sigmaNew) {
            sigma = sigmaNew;
            break;
        }
        sigma = sigmaNew;
    }
    b.copy(*eig, *v);
    haveEig = true;
    return 1.2 * std::max(sigma, 1.0);
}

double RKC2Control::step(StepWork& work, double maxDt) {
    // Damped second-order Runge-Kutta-Chebyshev with error control: knotmm's RKC2.
    RPYBackend& b = work.backend;
    RPYIntegrator& integrator = *work.integrator;
    const StateVector& y = *work.y;
    const double tol = integrator.getErrorTolerance();
    if (!work.k1.valid) {
        work.velocity(y, *work.k1.v);
        work.keepVelocity(y);
    }
    const StateVector& f0 = *work.k1.v;
    if (!haveRho || stepsSinceRho >= RHO_INTERVAL) {
        rho = spectralRadius(work, f0);
        haveRho = true;
        stepsSinceRho = 0;
    }
    while (true) {
        const double hTry = integrator.getStepSize();
        double h = std::min(hTry, maxDt);
        int s = 1 + (int) std::sqrt(1.0 + 1.54 * h * rho);
        if (s > MAX_STAGES) {
            s = MAX_STAGES;
            h = std::min(h, 0.653 * (s * s - 1) / rho);
        }
        s = std::max(s, 2);
        const ChebyshevCoefficients& c = chebyshev(s);
        b.copy(*prev2, y);
        b.combine(*prev, {times(1.0, y), times(c.muT[1] * h, f0)});
        for (int j = 2; j <= s; j++) {
            work.velocity(*prev, *k2);
            const double cy = 1.0 - c.mu[j] - c.nu[j], cf = c.muT[j] * h, cg = c.gammaT[j] * h;
            b.combine(*ytmp, {times(cy, y), times(c.mu[j], *prev), times(c.nu[j], *prev2), times(cf, *k2),
                              times(cg, f0)});
            prev2.swap(prev);
            prev.swap(ytmp);
        }
        StateVector& y1 = *work.y1;
        b.copy(y1, *prev);
        work.velocity(y1, *k4);
        // err = 0.8 (y - y1) + 0.4 h (f0 + v(y1))
        b.combine(*err, {times(1.0, y), times(-1.0, y1)});
        b.combine(*sum, {times(1.0, f0), times(1.0, *k4)});
        b.combine(*err, {times(0.8, *err), times(0.4 * h, *sum)});
        const double e = work.errorRatio(*err, tol);
        if (e <= 1.0) {
            // the error-per-step PI rule of the RKC code
            double fac = 10.0;
            if (e > 0) {
                if (!haveErrOld || !haveHOld)
                    fac = std::min(fac, 0.8 * std::pow(e, -1.0 / 3.0));
                else
                    fac = std::min(fac, 0.8 * (h / hOld) * std::pow(errOld, 1.0 / 3.0) / std::pow(e, 2.0 / 3.0));
            }
            fac = std::max(0.1, fac);
            if (!(h < hTry && fac >= 1.0)) {  // a step clipped to land keeps the wanted size
                errOld = std::max(e, 1e-10);
                haveErrOld = true;
                hOld = h;
                haveHOld = true;
                integrator.setStepSize(std::min(integrator.getMaximumStepSize(), h * fac));
            }
            lastStages = s;
            work.k1.v.swap(k4);
            work.keepVelocity(y1);
            stepsSinceRho++;
            return h;
        }
        const double fac = std::isfinite(e) ? std::max(0.1, 0.8 * std::pow(e, -1.0 / 3.0)) : 0.1;
        work.reject(h * fac, e, "; the last good state is kept");
        rho = spectralRadius(work, f0);
        haveRho = true;
        stepsSinceRho = 0;
        haveErrOld = false;
    }
}
