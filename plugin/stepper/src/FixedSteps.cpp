#include "knotmm/stepper/FixedSteps.h"

#include "openmm/OpenMMException.h"

#include <cmath>

using namespace KnotMM;

FixedSteps::FixedSteps(RPYBackend& backend)
    : k2(backend.createVector()), ytmp(backend.createVector()), w(backend.createVector()),
      sum(backend.createVector()) {
    held.kick = backend.createVector();
    held.positions = backend.createVector();
}

double FixedSteps::step(StepWork& work, double h) {
    RPYBackend& b = work.backend;
    const StateVector& y = *work.y;
    StateVector& y1 = *work.y1;
    StateVector& k1 = *work.k1.v;
    switch (work.method) {
    case RPYMethod::Euler:
    case RPYMethod::EulerMaruyama:
        // y1 = y + h v(y) + sqrt(2 kT h) B(y) xi
        work.noiseSample(y, std::sqrt(2.0 * work.kT * h), *w);
        work.velocity(y, k1);
        b.combine(y1, {times(1.0, y), times(h, k1), times(1.0, *w)});
        break;
    case RPYMethod::Heun:
    case RPYMethod::ItoHeun:
        // y* = y + h v(y) + W;  y1 = y + h/2 (v(y) + v(y*)) + W;  W = sqrt(2 kT h) B(y) xi
        work.noiseSample(y, std::sqrt(2.0 * work.kT * h), *w);
        work.velocity(y, k1);
        b.combine(*ytmp, {times(1.0, y), times(h, k1), times(1.0, *w)});
        work.velocity(*ytmp, *k2);
        b.combine(*sum, {times(1.0, k1), times(1.0, *k2)});
        b.combine(y1, {times(1.0, y), times(0.5 * h, *sum), times(1.0, *w)});
        break;
    case RPYMethod::LeimkuhlerMatthews: {
        // p = y + h v(y) + k;  k <- sqrt(kT h / 2) B(p) xi (held for the next step);  y1 = p + k
        // (the first held kick is drawn at y); at kT = 0 it is euler
        work.velocity(y, k1);
        if (work.kT == 0.0) {
            b.combine(y1, {times(1.0, y), times(h, k1)});
            break;
        }
        const double scale = std::sqrt(0.5 * work.kT * h);
        if (!held.valid) {
            work.noiseSample(y, scale, *held.kick);
            held.valid = true;
        }
        b.combine(*ytmp, {times(1.0, y), times(h, k1), times(1.0, *held.kick)});
        work.noiseSample(*ytmp, scale, *held.kick);
        b.combine(y1, {times(1.0, *ytmp), times(1.0, *held.kick)});
        break;
    }
    case RPYMethod::Midpoint:
        // y1 = y + h v(y + h/2 v(y))
        work.velocity(y, k1);
        b.combine(*ytmp, {times(1.0, y), times(0.5 * h, k1)});
        work.velocity(*ytmp, *k2);
        b.combine(y1, {times(1.0, y), times(h, *k2)});
        break;
    default:
        throw OpenMM::OpenMMException("RPYIntegrator: internal error (fixed step of an adaptive method)");
    }
    return h;
}
