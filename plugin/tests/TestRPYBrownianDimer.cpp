// A Brownian dimer samples Boltzmann's bond-length distribution.
//
// Two beads joined by a harmonic bond (HarmonicBondForce, energy k/2 (r - r0)^2) at kT > 0.
// Whatever the mobility, overdamped dynamics with noise sqrt(2 kT) B dW, B B^T = mu, has the
// Boltzmann distribution as its equilibrium (the RPY tensor is divergence-free, so no drift
// term is needed; shared/model.md). In 3D the bond length r then has the density
//   p(r) ~ r^2 exp(-k (r - r0)^2 / (2 kT)),
// whose mean and variance are computed here by Simpson quadrature (independent of the plugin;
// the mean is r0 + ~2 kT/(k r0), not r0: the r^2 is the 3D Jacobian).
//
// Parameters: d = mu0 = 1, kT = 1, k = 25, r0 = 1.5 (sigma = sqrt(kT/k) = 0.2; r dips into
// the overlap region r < d now and then). The bond relaxes at lambda = 2 k (mu0 - mu_par(r0))
// = 26.85 / ps (mu_par as in TestRPYDimerRelaxation), tau = 1/lambda = 0.037 ps.
//
// Methods, with z = lambda h, Cholesky noise:
//   * leimkuhler_matthews at z = 0.2: its stationary variance of a linear mode is exact, so
//     Boltzmann's moments are expected, no bias allowance;
//   * ito_heun at z = 0.1: the stationary variance of a linear mode is (1 - z^2/4 + ...)
//     times the exact one (closed form of the scheme's linear recursion): 0.25 % allowed;
//   * euler_maruyama at z = 0.1, as a check that the test resolves a step bias: for a linear
//     mode its stationary variance is exactly 1/(1 - z/2) = 1.053 times the true one, which is
//     what is expected here (the radial coordinate is nearly linear; a further 0.5 % of
//     sigma^2 is allowed for that). Its mean is expected unbiased.
//
// Statistics: each method runs 4 seeds x 1500 ps after 1 ps of burn-in (6000 ps = 1.6e5 tau),
// sampling r every step. For an Ornstein-Uhlenbeck mode of relaxation time tau observed for
// T, the standard error of the mean of r is sigma sqrt(2 tau / T) and that of the variance
// sigma^2 sqrt(2 tau / T) (r^2 decorrelates twice as fast but has variance 2 sigma^4): 0.35 %
// of sigma resp. sigma^2 here. The test asserts |measured - expected| <= 4 standard errors
// (+ the bias allowances above), and, as a check of that error model (it also checks that the
// fluctuations relax at the right rate), that the standard errors estimated from the scatter
// of 40 blocks (4 seeds x 10 blocks of 150 ps = 4000 tau each) lie within a factor 2 of these.
// With fixed seeds the test is deterministic on a given build; on another build (other
// rounding, other trajectories) the chance of a false failure is ~1e-4 per check.
// For scale: leaving out the r^2 Jacobian would shift the mean by 0.052 nm (~70 standard
// errors); uncorrelated noise sqrt(2 kT mu0) instead of B would inflate the variance by
// mu0 / (mu0 - mu_par(r0)) = 1.86.
//
// Measured with longer runs (4 x 10000 ps) while writing this test: ito_heun at z = 0.1 and
// 0.05 within 1.6 standard errors of Boltzmann; euler_maruyama at z = 0.05 +2.66 % in the
// variance (1/(1 - z/2) predicts +2.56 %); leimkuhler_matthews at z = 0.4 +0.4 %.

#include "TestUtilities.h"

#include <chrono>

using namespace OpenMM;
using namespace knotmm_test;

namespace {

const double KT = 1.0, K = 25.0, R0 = 1.5;

/** Mean and variance of r under p(r) ~ r^2 exp(-k (r-r0)^2 / (2kT)), Simpson's rule. */
void boltzmannMoments(double& mean, double& variance) {
    const double sigma = std::sqrt(KT / K);
    const double lo = std::max(0.0, R0 - 14.0 * sigma), hi = R0 + 14.0 * sigma;
    const int n = 200000;  // even
    const double dr = (hi - lo) / n;
    double m0 = 0.0, m1 = 0.0, m2 = 0.0;
    for (int i = 0; i <= n; i++) {
        const double r = lo + i * dr;
        const double w = (i == 0 || i == n) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
        const double p = w * r * r * std::exp(-K * (r - R0) * (r - R0) / (2.0 * KT));
        m0 += p;
        m1 += p * r;
        m2 += p * r * r;
    }
    mean = m1 / m0;
    variance = m2 / m0 - mean * mean;
}

double parallelMobility(double r) {
    return r >= 1.0 ? 0.75 / r - 0.125 / (r * r * r) : 1.0 - 0.375 * r;
}

struct Blocks {
    std::vector<double> sum, sum2;
    std::vector<long long> count;
};

void sample(const std::string& method, double z, double varianceFactor, double varianceAllowance, int seedBase) {
    const double lambda = 2.0 * K * (1.0 - parallelMobility(R0));
    const double tau = 1.0 / lambda, h = z / lambda;
    const int seeds = 4, blocksPerSeed = 10;
    const double burnIn = 1.0, runTime = 1500.0;
    const long long stepsPerBlock = (long long) std::llround(runTime / blocksPerSeed / h);
    Blocks blocks;
    const auto started = std::chrono::steady_clock::now();
    for (int seed = 1; seed <= seeds; seed++) {
        System system;
        system.addParticle(1.0);
        system.addParticle(1.0);
        HarmonicBondForce* bond = new HarmonicBondForce();
        bond->addBond(0, 1, R0, K);
        system.addForce(bond);
        KnotMM::RPYIntegrator integrator(h, method);
        integrator.setThermalEnergy(KT);
        integrator.setRandomNumberSeed(seedBase + seed);
        Context* context = makeContext(system, integrator, "Reference");
        context->setPositions({Vec3(0, 0, 0), Vec3(R0, 0, 0)});
        integrator.step((int) std::llround(burnIn / h));
        for (int b = 0; b < blocksPerSeed; b++) {
            double s = 0.0, s2 = 0.0;
            for (long long i = 0; i < stepsPerBlock; i++) {
                integrator.step(1);
                const std::vector<Vec3> x = positionsOf(*context);
                const Vec3 sep = x[1] - x[0];
                const double r = std::sqrt(sep.dot(sep));
                s += r;
                s2 += r * r;
            }
            blocks.sum.push_back(s);
            blocks.sum2.push_back(s2);
            blocks.count.push_back(stepsPerBlock);
        }
        delete context;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();

    // pooled estimates, and block-to-block scatter as a second estimate of their errors
    double total = 0.0, total2 = 0.0, count = 0.0;
    for (size_t b = 0; b < blocks.sum.size(); b++) {
        total += blocks.sum[b];
        total2 += blocks.sum2[b];
        count += blocks.count[b];
    }
    const double mean = total / count, variance = total2 / count - mean * mean;
    const int nb = blocks.sum.size();
    double scatterMean = 0.0, scatterVar = 0.0;
    for (int b = 0; b < nb; b++) {
        const double bm = blocks.sum[b] / blocks.count[b];
        const double bv = blocks.sum2[b] / blocks.count[b] - 2.0 * mean * bm + mean * mean;
        scatterMean += (bm - mean) * (bm - mean);
        scatterVar += (bv - variance) * (bv - variance);
    }
    const double seMeanBlocks = std::sqrt(scatterMean / (nb - 1) / nb);
    const double seVarBlocks = std::sqrt(scatterVar / (nb - 1) / nb);

    double expectedMean, expectedVar;
    boltzmannMoments(expectedMean, expectedVar);
    expectedVar *= varianceFactor;
    const double sigma2 = KT / K, observed = count * h;
    const double seMean = std::sqrt(sigma2 * 2.0 * tau / observed);
    const double seVar = sigma2 * std::sqrt(2.0 * tau / observed);
    std::printf("  %s: h = %.5g ps (lambda h = %.2f), %.0f samples over %.0f ps, %.1f s\n", method.c_str(), h, z,
                count, observed, seconds);
    std::printf("  %s: standard errors, OU model / from %d blocks: mean %.3g / %.3g nm, variance %.3g / %.3g nm^2\n",
                method.c_str(), nb, seMean, seMeanBlocks, seVar, seVarBlocks);
    std::printf("  %s: mean deviation %.2f standard errors, variance deviation %.2f standard errors\n",
                method.c_str(), (mean - expectedMean) / seMean, (variance - expectedVar) / seVar);
    KT_CHECK_ABS(method + ": <r> (Boltzmann, r^2 Jacobian)", expectedMean, mean, 4.0 * seMean);
    KT_CHECK_ABS(method + ": var(r)" + (varianceFactor != 1.0 ? " (x the linear-mode bias)" : ""), expectedVar,
                 variance, 4.0 * seVar + varianceAllowance * sigma2);
    KT_ASSERT(seMeanBlocks > 0.5 * seMean && seMeanBlocks < 2.0 * seMean);
    KT_ASSERT(seVarBlocks > 0.5 * seVar && seVarBlocks < 2.0 * seVar);
}

} // namespace

int main() {
    return runTest("TestRPYBrownianDimer: Boltzmann bond length of a Brownian dimer", [] {
        double mean, variance;
        boltzmannMoments(mean, variance);
        std::printf("  Boltzmann (quadrature): <r> = %.10f nm, var(r) = %.10f nm^2 (r0 = %g, kT/k = %g)\n", mean,
                    variance, R0, KT / K);
        sample("leimkuhler_matthews", 0.2, 1.0, 0.0, 100);
        sample("ito_heun", 0.1, 1.0, 0.1 * 0.1 / 4.0, 200);
        sample("euler_maruyama", 0.1, 1.0 / (1.0 - 0.1 / 2.0), 0.005, 300);
    });
}
