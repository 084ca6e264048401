// The device backend (plugin/platforms/common: CommonRPYBackend on OpenMM's ComputeContext)
// against independent references, on every device platform present (OpenCL in double and in
// mixed precision; pocl on the build machine). Skipped, with the reason printed, where none is.
//
// What is expected, and why it is independent of the device code:
//   1. velocity: one euler step of clusters of 45 and 100 beads (two and four work-group tiles
//      of 32 beads, the last one partly filled) with overlapping pairs (r < d) under
//      constant per-bead forces F_j (a CustomExternalForce; the values are exact in single
//      precision, as OpenMM's device platforms store per-particle parameters): (x1 - x0) / h
//      against v_i = sum_j mu_ij F_j by naiveMobilityTimes (TestUtilities.h: the textbook RPY
//      blocks with explicit branches). Allowed: 1e-8 d/tau_d (the force arrives in 64-bit fixed
//      point, 2^-32 per component; positions are read back to ~1e-15 d).
//   2. rk23 (and rkc2) over 3 tau_d, a ring of 40 beads (bonds, bending, gravity), against the
//      Reference platform: the same method in double precision on the host. Double precision:
//      within 1e-7 d. Mixed precision computes forces in single precision (relative ~1e-7):
//      within 1e-4 d. rk23 evaluates 1 + 3 (accepted + rejected) times on the device too (the
//      cached FSAL velocity survives the round trip of positions through the Context, also in
//      mixed precision).
//   3. A chain translated by (1e4, -1e4, 1e4) d moves as the same chain at the origin (rk23,
//      1 tau_d): forces are evaluated with the beads shifted to their centre of mass, and the
//      stepper keeps the state in double in every precision. Allowed: 1e-9 d in double and in
//      mixed precision (without the shift, single-precision forces at 1e4 d would see positions
//      rounded to 1e-3 d; with the state read back from the Context each step, as before
//      backend v2, mixed precision was 5.2e-7 d off).
//   4. Brownian: euler_maruyama, fixed step 1e-3, kT = 1, seed 1234, Cholesky noise, the ring:
//      the first 20 steps equal the Reference platform's to 1e-9 d (double; mixed 1e-6 d): the
//      normals are the counter-based stream's (made on the device there, on the host here),
//      the Cholesky factor from the same host code.
//   5. A virtual site (the midpoint of beads 0 and 2, particle 1 of 4, with a force of its own)
//      is placed by OpenMM, is not a bead, and hands its force to the beads: rk23 to 0.5 tau_d
//      against the Reference platform (1e-8 d double, 1e-5 d mixed), the site at the midpoint.
//   6. getGroupEnergies leaves the Context as it was: 5 steps, energies, 5 steps equals 10 steps
//      bit for bit (positions, step size, evaluations); the energies agree with the Reference
//      platform's at its own state (1e-6 max(1, |E|); mixed precision, whose energy terms are
//      computed in single precision, 1e-4 max(1, |E|); single precision 1e-3 max(1, |E|)).
//   7. Overflow (device forces are fixed point, so they are never NaN; positions can still
//      overflow): euler at h = 1e308 under a constant force raises RPYStepFault non_finite for
//      bead 1 and keeps the state; rk23 tried at h = 1e300 on dy/dt = -y rejects its tries
//      while the error estimate is not finite (as many as the Reference platform), then takes
//      the Reference platform's step.
//   8. Single precision (OpenMM's default on a device): the backend keeps the positions in
//      double and the Context holds floats of them: checks 2, 4, 5, 6 and 7 at single-precision
//      tolerances (what is read back is rounded to floats), and a Context made without
//      properties steps the ring as the Reference platform does (1e-4 d); after loadCheckpoint
//      it continues bit for bit (the checkpoint holds the state in double).

#include "TestSystems.h"
#include "TestUtilities.h"
#include "knotmm/RPYStepFault.h"

#include <cstdint>
#include <memory>
#include <sstream>

using namespace OpenMM;
using namespace knotmm_test;

namespace {


/** Deterministic uniform numbers in [lo, hi) (a 64-bit LCG: the test needs no library RNG). */
struct Uniform {
    uint64_t state;
    explicit Uniform(uint64_t seed) : state(seed) {}
    double operator()(double lo, double hi) {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        return lo + (hi - lo) * ((state >> 11) * (1.0 / 9007199254740992.0));
    }
};

/** The tolerance for the platform's precision ("OpenCL:double", ":mixed", ":single"). */
double byPrecision(const std::string& platform, double dbl, double mixed, double single) {
    if (platform.find("single") != std::string::npos)
        return single;
    return platform.find("mixed") != std::string::npos ? mixed : dbl;
}

// --- 1. velocity against the naive RPY ---------------------------------------------------------

void velocityAgainstNaive(const std::string& platform, int n) {
    Uniform u(2024 + n);
    Vecs x;
    const double side = 2.2 * std::cbrt(n / 12.0);
    while ((int) x.size() < n) {  // 12 beads in 2.2^3 d^3: many pairs closer than d, none closer than 0.1 d
        const Vec3 p(u(0, side), u(0, side), u(0, side));
        bool ok = true;
        for (const Vec3& q : x)
            ok = ok && (p - q).dot(p - q) > 0.01;
        if (ok)
            x.push_back(p);
    }
    int overlapping = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++)
            overlapping += (x[i] - x[j]).dot(x[i] - x[j]) < 1.0 ? 1 : 0;
    System system;
    CustomExternalForce* field = new CustomExternalForce("-(fx*x+fy*y+fz*z)");
    field->addPerParticleParameter("fx");
    field->addPerParticleParameter("fy");
    field->addPerParticleParameter("fz");
    Vecs f;
    for (int i = 0; i < n; i++) {
        system.addParticle(1.0);
        const double fx = singleRounded(u(-2, 2)), fy = singleRounded(u(-2, 2)), fz = singleRounded(u(-2, 2));
        f.push_back(Vec3(fx, fy, fz));  // exact in single precision
        field->addParticle(i, {f[i][0], f[i][1], f[i][2]});
    }
    system.addForce(field);
    const double h = 1e-3;
    KnotMM::RPYIntegrator integ(h, "euler");
    std::unique_ptr<Context> context(makeContext(system, integ, platform));
    context->setPositions(x);
    const Vecs x0 = positionsOf(*context);  // as the Context stores them
    integ.step(1);
    const Vecs x1 = positionsOf(*context);
    const Vecs expected = naiveMobilityTimes(x0, f, 1.0, 1.0);
    double worst = 0.0, largest = 0.0;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            worst = std::max(worst, std::fabs((x1[i][k] - x0[i][k]) / h - expected[i][k]));
            largest = std::max(largest, std::fabs(expected[i][k]));
        }
    std::printf("  %-13s velocity of %d beads (%d pairs with r < d), largest |v| %.3g\n", platform.c_str(), n,
                overlapping, largest);
    KT_ASSERT(overlapping >= n / 2);
    KT_CHECK_ABS(platform + ": max |v - v_naive|", 0.0, worst, 1e-8);
}

// --- 2. rk23 / rkc2 on a ring against the Reference platform -------------------------------------

struct RunResult {
    Vecs x;
    long long accepted, rejected, evaluations;
};

RunResult runTo(System& system, const Vecs& start, const std::string& platform, const std::string& method,
                double time) {
    KnotMM::RPYIntegrator integ(0.001, method, 1e-4);
    std::unique_ptr<Context> context(makeContext(system, integ, platform));
    context->setPositions(start);
    integ.stepTo(time);
    return {positionsOf(*context), integ.getNumAcceptedSteps(), integ.getNumRejectedSteps(),
            integ.getNumForceEvaluations()};
}

void ringAgainstReference(const std::string& platform) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(40, start));
    for (const char* method : {"rk23", "rkc2"}) {
        const RunResult ref = runTo(*system, start, "Reference", method, 3.0);
        const RunResult dev = runTo(*system, start, platform, method, 3.0);
        std::printf("  %-13s %-5s ring of 40 to t = 3: %lld accepted, %lld rejected, %lld evaluations "
                    "(Reference: %lld, %lld, %lld); moved %.3g d\n",
                    platform.c_str(), method, dev.accepted, dev.rejected, dev.evaluations, ref.accepted, ref.rejected,
                    ref.evaluations, maxDeviation(ref.x, start));
        KT_CHECK_ABS(platform + " " + method + ": max |x - x_Reference| at t = 3", 0.0, maxDeviation(dev.x, ref.x),
                     byPrecision(platform, 1e-7, 1e-4, 1e-4));
        if (std::string(method) == "rk23")
            KT_ASSERT(dev.evaluations == 1 + 3 * (dev.accepted + dev.rejected));
    }
}

// --- 3. far from the origin ----------------------------------------------------------------------

void farFromOrigin(const std::string& platform) {
    const double offset = 1e4;
    Vecs near, far;
    std::unique_ptr<System> a(ringSystem(20, near, 0.0, true)), b(ringSystem(20, far, offset, true));
    const RunResult atOrigin = runTo(*a, near, platform, "rk23", 1.0);
    const RunResult away = runTo(*b, far, platform, "rk23", 1.0);
    std::printf("  %-13s chain of 20 at the origin / at 1e4 d: %lld / %lld accepted steps, moved %.3g d\n",
                platform.c_str(), atOrigin.accepted, away.accepted, maxDeviation(atOrigin.x, near));
    KT_CHECK_ABS(platform + ": chain at 1e4 d against the same at the origin (t = 1)", 0.0,
                 maxDeviation(away.x, atOrigin.x, Vec3(offset, -offset, offset)), byPrecision(platform, 1e-9, 1e-9, 1e-5));
}

// --- 4. Brownian steps against the Reference platform ------------------------------------------

void brownianAgainstReference(const std::string& platform) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(40, start));
    KnotMM::RPYIntegrator refInteg(1e-3, "euler_maruyama"), devInteg(1e-3, "euler_maruyama");
    for (KnotMM::RPYIntegrator* integ : {&refInteg, &devInteg}) {
        integ->setThermalEnergy(1.0);
        integ->setRandomNumberSeed(1234);
    }
    std::unique_ptr<Context> ref(makeContext(*system, refInteg, "Reference"));
    std::unique_ptr<Context> dev(makeContext(*system, devInteg, platform));
    ref->setPositions(start);
    dev->setPositions(start);
    double worst = 0.0;
    for (int s = 0; s < 20; s++) {
        refInteg.step(1);
        devInteg.step(1);
        worst = std::max(worst, maxDeviation(positionsOf(*dev), positionsOf(*ref)));
    }
    std::printf("  %-13s euler_maruyama (kT = 1) moved %.3g d in 20 steps\n", platform.c_str(),
                maxDeviation(positionsOf(*ref), start));
    KT_CHECK_ABS(platform + ": Brownian steps 1-20, max |x - x_Reference|", 0.0, worst, byPrecision(platform, 1e-9, 1e-6, 1e-5));
}

// --- 5. a virtual site -----------------------------------------------------------------------------

void virtualSite(const std::string& platform) {
    // particles: bead 0, the site (midpoint of 0 and 2), bead 2, bead 3
    System system;
    for (int i = 0; i < 4; i++)
        system.addParticle(i == 1 ? 0.0 : 1.0);
    system.setVirtualSite(1, new TwoParticleAverageSite(0, 2, 0.5, 0.5));
    HarmonicBondForce* bonds = new HarmonicBondForce();
    bonds->addBond(0, 2, 0.75, 20.0);  // exact in single precision, as above
    bonds->addBond(2, 3, 0.75, 20.0);
    system.addForce(bonds);
    CustomExternalForce* push = new CustomExternalForce("-f*z");  // on the site only
    push->addPerParticleParameter("f");
    push->addParticle(1, {1.5});
    system.addForce(push);
    const Vecs start = {Vec3(0, 0, 0), Vec3(), Vec3(0.9, 0.1, 0), Vec3(1.5, 0.7, 0.2)};
    const RunResult ref = runTo(system, start, "Reference", "rk23", 0.5);
    const RunResult dev = runTo(system, start, platform, "rk23", 0.5);
    const Vec3 mid = (dev.x[0] + dev.x[2]) * 0.5;
    std::printf("  %-13s virtual site: the site moved %.3g d up\n", platform.c_str(), dev.x[1][2]);
    KT_ASSERT(dev.x[1][2] > 0.1);
    KT_CHECK_ABS(platform + ": virtual site run, max |x - x_Reference|", 0.0, maxDeviation(dev.x, ref.x),
                 byPrecision(platform, 1e-8, 1e-5, 1e-5));
    KT_CHECK_ABS(platform + ": the site at the midpoint of its beads", 0.0, maxDeviation({dev.x[1]}, {mid}),
                 byPrecision(platform, 1e-12, 1e-6, 1e-6));
}

// --- 6. getGroupEnergies leaves the Context as it was ------------------------------------------

void groupEnergies(const std::string& platform) {
    Vecs start;
    std::unique_ptr<System> system(ringSystem(40, start));
    std::vector<double> energies[2];
    Vecs after[2];
    long long evaluations[2];
    double stepSize[2];
    for (int withEnergies = 0; withEnergies < 2; withEnergies++) {
        KnotMM::RPYIntegrator integ(0.001, "rk23", 1e-4);
        std::unique_ptr<Context> context(makeContext(*system, integ, withEnergies ? platform : "Reference"));
        context->setPositions(start);
        integ.step(5);
        energies[withEnergies] = integ.getGroupEnergies({0, 1, 2});
        if (withEnergies == 0) {
            // the same on the device without the energies in between: the reference for "as it was"
            KnotMM::RPYIntegrator plain(0.001, "rk23", 1e-4);
            std::unique_ptr<Context> other(makeContext(*system, plain, platform));
            other->setPositions(start);
            plain.step(10);
            after[0] = positionsOf(*other);
            evaluations[0] = plain.getNumForceEvaluations();
            stepSize[0] = plain.getStepSize();
        }
        else {
            integ.step(5);
            after[1] = positionsOf(*context);
            evaluations[1] = integ.getNumForceEvaluations();
            stepSize[1] = integ.getStepSize();
        }
    }
    // (gravity's energy is the shifted one: 0 up to rounding, as the beads' mean height is 0)
    for (int g = 0; g < 3; g++)
        KT_CHECK_ABS(platform + ": group " + std::to_string(g) + " energy after 5 steps (against Reference)",
                     energies[0][g], energies[1][g],
                     byPrecision(platform, 1e-6, 1e-4, 1e-3) * std::max(1.0, std::fabs(energies[0][g])));
    KT_ASSERT(after[0] == after[1]);
    KT_ASSERT(evaluations[0] == evaluations[1] && stepSize[0] == stepSize[1]);
    std::printf("  %-13s 5 steps, getGroupEnergies, 5 steps = 10 steps, bit for bit\n", platform.c_str());
}

// --- 7. steps that overflow -----------------------------------------------------------------------

void overflow(const std::string& platform) {
    // euler with h = 1e308 under a constant force: z + h v is +infinity, a non_finite fault
    {
        System system;
        system.addParticle(1.0);
        system.addParticle(1.0);
        CustomExternalForce* push = new CustomExternalForce("-4*z");
        push->addParticle(1, {});
        system.addForce(push);
        KnotMM::RPYIntegrator integ(1e308, "euler");
        std::unique_ptr<Context> context(makeContext(system, integ, platform));
        context->setPositions({Vec3(0, 0, 0), Vec3(5, 0, 1)});
        const Vecs before = positionsOf(*context);
        bool raised = false;
        try {
            integ.step(1);
        }
        catch (const KnotMM::RPYStepFault& fault) {
            raised = true;
            std::printf("  %-13s euler, h = 1e308: RPYStepFault %s (bead %d): %s\n", platform.c_str(),
                        fault.kindName(), fault.bead(), fault.what());
            KT_ASSERT(fault.kind() == KnotMM::RPYStepFault::NonFinite && fault.bead() == 1);
        }
        KT_ASSERT(raised);
        KT_ASSERT(positionsOf(*context) == before);
        KT_ASSERT(context->getState(State::Positions).getTime() == 0.0);
    }
    // rk23 tried at h = 1e300 on dy/dt = -y: the error estimate overflows (not finite), so the
    // try is rejected and the step shrinks (x0.2) until it is finite; the step then taken is the
    // Reference platform's
    System system;
    system.addParticle(1.0);
    system.addParticle(1.0);
    CustomExternalForce* spring = new CustomExternalForce("0.5*(x*x+y*y+z*z)");
    spring->addParticle(0, {});
    spring->addParticle(1, {});
    system.addForce(spring);
    const Vecs start = {Vec3(0.5, 0, 0), Vec3(3, 1, 2)};
    RunResult results[2];
    for (int which = 0; which < 2; which++) {
        KnotMM::RPYIntegrator integ(1e300, "rk23", 1e-4);
        integ.setMaximumStepSize(1e300);
        std::unique_ptr<Context> context(makeContext(system, integ, which == 0 ? "Reference" : platform));
        context->setPositions(start);
        integ.step(1);
        results[which] = {positionsOf(*context), integ.getNumAcceptedSteps(), integ.getNumRejectedSteps(),
                          integ.getNumForceEvaluations()};
    }
    std::printf("  %-13s rk23 from h = 1e300: %lld rejected tries (Reference: %lld)\n", platform.c_str(),
                results[1].rejected, results[0].rejected);
    KT_ASSERT(results[1].rejected > 100 && results[1].rejected == results[0].rejected);
    KT_CHECK_ABS(platform + ": rk23 after the overflowing tries, max |x - x_Reference|", 0.0,
                 maxDeviation(results[1].x, results[0].x), byPrecision(platform, 1e-9, 1e-6, 1e-6));
}

} // namespace

int main() {
    return runTest("TestRPYDevice: the device backend against independent references", [] {
        std::vector<std::string> devices;
        for (const std::string& name : platformNames())
            if (isDevice(name))
                devices.push_back(name);
        if (devices.empty()) {
            std::printf("  SKIPPED: no device platform (OpenCL: %s)\n", openclSkipReason().c_str());
            return;
        }
        for (const std::string& platform : devices) {
            for (int n : {45, 100})
                velocityAgainstNaive(platform, n);
            ringAgainstReference(platform);
            farFromOrigin(platform);
            brownianAgainstReference(platform);
            virtualSite(platform);
            groupEnergies(platform);
            overflow(platform);
        }
        // single precision (OpenMM's default on a device: a Context made without properties):
        // the backend keeps the positions in double, the Context holds floats of them (so
        // what a test reads back is rounded to ~1e-7 relative; the velocity and far-chain
        // checks, which read positions at 1e-12, are left out)
        const std::string single = "OpenCL:single";
        ringAgainstReference(single);
        brownianAgainstReference(single);
        virtualSite(single);
        groupEnergies(single);
        overflow(single);
        Vecs start;
        std::unique_ptr<System> system(ringSystem(40, start));
        KnotMM::RPYIntegrator integ(0.001, "rk23", 1e-4);
        Context context(*system, integ, Platform::getPlatformByName("OpenCL"));  // no properties
        KT_ASSERT(context.getPlatform().getPropertyValue(context, "Precision") == "single");
        context.setPositions(start);
        integ.stepTo(3.0);
        const RunResult ref = runTo(*system, start, "Reference", "rk23", 3.0);
        KT_CHECK_ABS("OpenCL, default properties (single): ring of 40 at t = 3 against Reference", 0.0,
                     maxDeviation(positionsOf(context), ref.x), 1e-4);
        // a checkpoint holds the stepper's state in double: the run continues bit for bit
        std::stringstream checkpoint;
        context.createCheckpoint(checkpoint);
        integ.step(25);
        const Vecs first = positionsOf(context);
        context.loadCheckpoint(checkpoint);
        integ.step(25);
        KT_CHECK_ABS("OpenCL single: 25 rk23 steps after loadCheckpoint against the uninterrupted run", 0.0,
                     maxDeviation(positionsOf(context), first), 0.0);
    });
}
