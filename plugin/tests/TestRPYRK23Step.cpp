// rk23 steps of a 3-bead chain against a hand computation written here.
//
// The reference is computed in this file from scratch: forces of the two harmonic bonds and
// of a constant field by hand (F = -k (r - r0) rhat), velocities by naiveMobilityTimes
// (TestUtilities.h: the RPY blocks of shared/model.md with explicit branches), and the
// Bogacki-Shampine 3(2) pair as published (Bogacki & Shampine 1989; knotmm's
// knotmm.dynamics.deterministic.RK23 documents the same tableau and controller):
//   k1 = v(y), k2 = v(y + h k1/2), k3 = v(y + 3h k2/4), y1 = y + h (2 k1 + 3 k2 + 4 k3)/9,
//   k4 = v(y1) (the next k1, FSAL), err = h (-5 k1/72 + k2/12 + k3/9 - k4/8),
//   e = max over beads |err_bead| / tol; accepted if e <= 1, then
//   h_next = min(h_max, h clip(0.9 e^(-0.7/3) e_old^(0.4/3), 0.2, 5)), e_old <- max(e, 1e-4)
//   (e_old = 1 at the start); rejected: h <- h max(0.2, 0.9 e^(-1/3)) and retry.
// The chain's pairs cover both RPY branches: 0-1 at 0.71 d and 1-2 at 0.98 d (overlap
// formula), 0-2 at 1.51 d (far field).
//
// Checks (Reference platform):
//   * three accepted steps from h = 0.004: positions after each equal the hand computation to
//     1e-12 nm (the displacements are ~1e-2 nm, so this is 1e-10 relative); the next step size
//     (getStepSize) to 1e-10 relative (it goes through e^(-0.7/3), whose argument is a
//     difference of stages: relative rounding ~1e-13); Context time = sum of the steps
//     (1e-12 relative);
//     force evaluations 1 + 3 per attempt; no rejection.
//   * a first try at h = 0.08 that the controller rejects (three times, as the hand computation
//     says): the same positions, step size, counts of rejections and evaluations.

#include "TestUtilities.h"

using namespace OpenMM;
using namespace knotmm_test;

namespace {

const double K = 50.0, R0 = 0.6, GRAVITY = 1.0, TOL = 1e-4, HMAX = 1.0;
typedef std::vector<Vec3> Vecs;

Vecs forces(const Vecs& x) {
    Vecs f(x.size(), Vec3(0.0, 0.0, -GRAVITY));
    for (int b = 0; b < 2; b++) {
        const Vec3 sep = x[b + 1] - x[b];
        const double r = std::sqrt(sep.dot(sep));
        const Vec3 pull = sep * (K * (r - R0) / r);  // force on bead b (towards b+1 if stretched)
        f[b] += pull;
        f[b + 1] -= pull;
    }
    return f;
}

Vecs velocity(const Vecs& x) { return naiveMobilityTimes(x, forces(x), 1.0, 1.0); }

Vecs axpy(const Vecs& y, double a, const Vecs& k) {
    Vecs out(y);
    for (size_t i = 0; i < y.size(); i++)
        out[i] += k[i] * a;
    return out;
}

/** The hand computation's state: what the plugin keeps between steps. */
struct Hand {
    Vecs y, k1;
    double h, errOld = 1.0, time = 0.0;
    long long evaluations = 0, rejected = 0;
    void step() {
        if (k1.empty()) {
            k1 = velocity(y);
            evaluations++;
        }
        while (true) {
            const Vecs k2 = velocity(axpy(y, 0.5 * h, k1));
            const Vecs k3 = velocity(axpy(y, 0.75 * h, k2));
            Vecs y1(y.size()), err(y.size());
            for (size_t i = 0; i < y.size(); i++)
                y1[i] = y[i] + (k1[i] * 2.0 + k2[i] * 3.0 + k3[i] * 4.0) * (h / 9.0);
            const Vecs k4 = velocity(y1);
            evaluations += 3;
            double e = 0.0;
            for (size_t i = 0; i < y.size(); i++) {
                err[i] = (k1[i] * (-5.0 / 72.0) + k2[i] * (1.0 / 12.0) + k3[i] * (1.0 / 9.0) - k4[i] * (1.0 / 8.0)) * h;
                e = std::max(e, std::sqrt(err[i].dot(err[i])) / TOL);
            }
            std::printf("  hand computation: try h = %.6g, error estimate %.6g x tol -> %s\n", h, e,
                        e <= 1.0 ? "accepted" : "rejected");
            if (e <= 1.0) {
                const double fac = e == 0.0 ? 5.0 : std::min(5.0, std::max(0.2, 0.9 * std::pow(e, -0.7 / 3.0) * std::pow(errOld, 0.4 / 3.0)));
                time += h;
                h = std::min(HMAX, h * fac);
                errOld = std::max(e, 1e-4);
                y = y1;
                k1 = k4;
                return;
            }
            rejected++;
            h *= std::max(0.2, 0.9 * std::pow(e, -1.0 / 3.0));
        }
    }
};

void compare(double h0, int steps, long long expectRejected) {
    const Vecs start = {Vec3(0.0, 0.0, 0.0), Vec3(0.7, 0.1, -0.05), Vec3(1.2, 0.9, 0.2)};
    System system;
    HarmonicBondForce* bonds = new HarmonicBondForce();
    for (int i = 0; i < 3; i++)
        system.addParticle(1.0);
    bonds->addBond(0, 1, R0, K);
    bonds->addBond(1, 2, R0, K);
    system.addForce(bonds);
    CustomExternalForce* field = new CustomExternalForce("g*z");
    field->addGlobalParameter("g", GRAVITY);
    for (int i = 0; i < 3; i++)
        field->addParticle(i, {});
    system.addForce(field);
    KnotMM::RPYIntegrator integrator(h0, "rk23", TOL);
    integrator.setMaximumStepSize(HMAX);
    Context* context = makeContext(system, integrator, "Reference");
    context->setPositions(start);

    Hand hand;
    hand.y = start;
    hand.h = h0;
    for (int s = 0; s < steps; s++) {
        integrator.step(1);
        hand.step();
        const Vecs x = positionsOf(*context);
        const std::string label = "h0 = " + std::to_string(h0) + ", after step " + std::to_string(s + 1);
        double worst = 0.0;
        for (int b = 0; b < 3; b++)
            for (int k = 0; k < 3; k++)
                worst = std::max(worst, std::fabs(x[b][k] - hand.y[b][k]));
        KT_CHECK_ABS(label + ": max |x - x_hand|", 0.0, worst, 1e-12);
        KT_CHECK_REL(label + ": next step size", hand.h, integrator.getStepSize(), 1e-10);
        KT_CHECK_REL(label + ": time", hand.time, context->getState(State::Positions).getTime(), 1e-12);
        KT_ASSERT(integrator.getNumAcceptedSteps() == s + 1);
        KT_ASSERT(integrator.getNumRejectedSteps() == hand.rejected);
        KT_ASSERT(integrator.getNumForceEvaluations() == hand.evaluations);
    }
    std::printf("  h0 = %g: %lld rejected, %lld force evaluations (hand computation: %lld, %lld)\n", h0,
                integrator.getNumRejectedSteps(), integrator.getNumForceEvaluations(), hand.rejected,
                hand.evaluations);
    KT_ASSERT(hand.rejected == expectRejected);
    delete context;
}

} // namespace

int main() {
    return runTest("TestRPYRK23Step: rk23 steps of a 3-bead chain against a hand computation", [] {
        compare(0.004, 3, 0);
        compare(0.08, 2, 3);
    });
}
