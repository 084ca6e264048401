#include "RPYMobility.h"

#include "openmm/internal/ThreadPool.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>

using namespace KnotMM;

namespace {

// Coefficients (a, b) of mu_ij / mu0 = a I + b rvec rvec^T (rvec unnormalised) from r^2, with
// one square root and one division and no branch (so the pair loop vectorises); r = 0 (the
// bead itself) gives the limit mu = I. invD = 1/d.
struct Coefficients {
    double a, b;
};

inline Coefficients pairCoefficients(double r2, double d, double invD) {
    const double inv = 1.0 / std::sqrt(r2 > 1e-300 ? r2 : 1e-300);
    const double r = r2 * inv;
    const double s = d * inv;  // d / r
    const double s2 = s * s;
    const double aFar = 0.375 * s * (1.0 + s2 / 6.0);
    const double bFar = 0.375 * s * (1.0 - 0.5 * s2) * (inv * inv);
    const double aNear = 1.0 - 0.5625 * r * invD;
    const double bNear = 0.1875 * inv * invD;
    const double a = r >= d ? aFar : aNear;
    const double b = r >= d ? bFar : bNear;
    return {r2 == 0.0 ? 1.0 : a, r2 == 0.0 ? 0.0 : b};
}

} // namespace

RPYMobility::RPYMobility(double diameter, double mu0, int numThreads)
    : d(diameter), mu0(mu0), numThreads(std::max(1, numThreads)) {
    if (this->numThreads > 1)
        pool.reset(new OpenMM::ThreadPool(this->numThreads));
}

RPYMobility::~RPYMobility() = default;
RPYMobility::RPYMobility(RPYMobility&&) noexcept = default;
RPYMobility& RPYMobility::operator=(RPYMobility&&) noexcept = default;

// The pair loop is compiled twice, for AVX2+FMA (x86-64-v3) and for the baseline, and the
// loader picks the one the processor runs (GCC function multiversioning), so a build runs on
// any x86-64 machine and is fast on current ones.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define KNOTMM_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define KNOTMM_CLONES
#endif

KNOTMM_CLONES
void RPYMobility::rows(int n, const double* x, const double* f, double* v, int begin, int end) const {
    const double* xs = x;
    const double* ys = x + n;
    const double* zs = x + 2 * n;
    const double* fx = f;
    const double* fy = f + n;
    const double* fz = f + 2 * n;
    const double invD = 1.0 / d;
    for (int i = begin; i < end; i++) {
        const double xi = xs[i], yi = ys[i], zi = zs[i];
        double ax = 0.0, ay = 0.0, az = 0.0;
        // Each row reads all beads and accumulates in registers (the full N^2 loop, not the
        // half loop that scatters into v[j]): it vectorises and rows are independent.
#pragma omp simd reduction(+ : ax, ay, az)
        for (int j = 0; j < n; j++) {
            const double r0 = xs[j] - xi;
            const double r1 = ys[j] - yi;
            const double r2 = zs[j] - zi;
            const Coefficients c = pairCoefficients(r0 * r0 + r1 * r1 + r2 * r2, d, invD);
            const double rf = c.b * (r0 * fx[j] + r1 * fy[j] + r2 * fz[j]);
            ax += c.a * fx[j] + rf * r0;
            ay += c.a * fy[j] + rf * r1;
            az += c.a * fz[j] + rf * r2;
        }
        v[i] = mu0 * ax;
        v[n + i] = mu0 * ay;
        v[2 * n + i] = mu0 * az;
    }
}

void RPYMobility::velocities(int n, const double* x, const double* f, double* v) const {
    // Below a few hundred beads waking the workers costs more than the loop saves.
    const int threads = std::min(numThreads, std::max(1, n / 128));
    if (threads <= 1 || !pool) {
        rows(n, x, f, v, 0, n);
        return;
    }
    // Row i costs the same for every i: equal blocks, one per worker (rows are independent,
    // so the result does not depend on the number of threads).
    pool->execute([&](OpenMM::ThreadPool&, int index) {
        if (index < threads)
            rows(n, x, f, v, (int) ((long long) n * index / threads),
                 (int) ((long long) n * (index + 1) / threads));
    });
    pool->waitForThreads();
}

template <class Real>
void RPYMobility::lowerMatrix(int n, const double* x, std::vector<Real>& m) const {
    // Row by row (bead i, then its three rows), blocks j <= i only: contiguous writes, half
    // the pairs of a full fill, and nothing above the diagonal is touched (the Cholesky
    // routines read only the lower triangle). Every entry is computed in double precision and
    // then stored as Real.
    const int dim = 3 * n;
    m.resize((size_t) dim * dim);
    const double invD = 1.0 / d;
    for (int i = 0; i < n; i++) {
        Real* rows[3] = {&m[(size_t) (3 * i) * dim], &m[(size_t) (3 * i + 1) * dim], &m[(size_t) (3 * i + 2) * dim]};
        for (int j = 0; j < i; j++) {
            const double rv[3] = {x[j] - x[i], x[n + j] - x[n + i], x[2 * n + j] - x[2 * n + i]};
            const Coefficients c = pairCoefficients(rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2], d, invD);
            for (int k = 0; k < 3; k++)
                for (int l = 0; l < 3; l++)
                    rows[k][3 * j + l] = (Real) (mu0 * (c.b * rv[k] * rv[l] + (k == l ? c.a : 0.0)));
        }
        for (int k = 0; k < 3; k++)
            for (int l = 0; l <= k; l++)
                rows[k][3 * i + l] = (Real) (k == l ? mu0 : 0.0);
    }
}

template void RPYMobility::lowerMatrix<double>(int, const double*, std::vector<double>&) const;
template void RPYMobility::lowerMatrix<float>(int, const double*, std::vector<float>&) const;

namespace {
// LAPACK dpotrf and spotrf (Fortran convention: every argument by pointer), or null for the
// built-in routine. Atomic: set once from Python, read by every factorisation.
typedef void (*PotrfRoutine)(char* uplo, int* n, double* a, int* lda, int* info);
typedef void (*SinglePotrfRoutine)(char* uplo, int* n, float* a, int* lda, int* info);
std::atomic<PotrfRoutine> potrfRoutine{nullptr};
std::atomic<SinglePotrfRoutine> singlePotrfRoutine{nullptr};

// The row-major array is the column-major transpose, which is the same symmetric matrix;
// LAPACK's upper factor U (A = U^T U, column-major) is then L = U^T in the row-major lower
// triangle. LAPACK leaves the other triangle as it was: zero it.
template <class Real, class Routine>
bool lapackLower(Routine potrf, std::vector<Real>& a, int n) {
    char uplo = 'U';
    int size = n, lda = n, info = 0;
    potrf(&uplo, &size, a.data(), &lda, &info);
    if (info != 0)
        return false;
    for (int i = 0; i < n; i++)
        std::fill(a.begin() + (size_t) i * n + i + 1, a.begin() + (size_t) (i + 1) * n, (Real) 0);
    return true;
}
} // namespace

void KnotMM::setCholeskyRoutine(unsigned long long address) {
    potrfRoutine.store(reinterpret_cast<PotrfRoutine>(static_cast<uintptr_t>(address)));
}

unsigned long long KnotMM::getCholeskyRoutine() {
    return static_cast<unsigned long long>(reinterpret_cast<uintptr_t>(potrfRoutine.load()));
}

void KnotMM::setSingleCholeskyRoutine(unsigned long long address) {
    singlePotrfRoutine.store(reinterpret_cast<SinglePotrfRoutine>(static_cast<uintptr_t>(address)));
}

unsigned long long KnotMM::getSingleCholeskyRoutine() {
    return static_cast<unsigned long long>(reinterpret_cast<uintptr_t>(singlePotrfRoutine.load()));
}

bool KnotMM::choleskyLower(std::vector<double>& a, int n) {
    PotrfRoutine potrf = potrfRoutine.load();
    return potrf == nullptr ? choleskyLowerBuiltin(a, n) : lapackLower(potrf, a, n);
}

bool KnotMM::choleskyLower(std::vector<float>& a, int n) {
    SinglePotrfRoutine potrf = singlePotrfRoutine.load();
    if (potrf != nullptr)
        return lapackLower(potrf, a, n);
    // no spotrf handed over: the built-in routine in double precision, rounded
    std::vector<double> wide(a.begin(), a.end());
    if (!choleskyLowerBuiltin(wide, n))
        return false;
    std::copy(wide.begin(), wide.end(), a.begin());
    return true;
}

namespace {
template <class Real>
inline void lowerTimesOf(const std::vector<Real>& lower, int n, const double* xi, double scale, double* out) {
    for (int i = 0; i < n; i++) {
        const Real* li = &lower[(size_t) i * n];
        double s = 0.0;
#pragma omp simd reduction(+ : s)
        for (int k = 0; k <= i; k++)
            s += (double) li[k] * xi[k];
        out[i] = scale * s;
    }
}
} // namespace

// One body for both precisions, compiled for each target of the clones.
KNOTMM_CLONES
void KnotMM::lowerTimes(const std::vector<double>& lower, int n, const double* xi, double scale, double* out) {
    lowerTimesOf(lower, n, xi, scale, out);
}

KNOTMM_CLONES
void KnotMM::lowerTimes(const std::vector<float>& lower, int n, const double* xi, double scale, double* out) {
    lowerTimesOf(lower, n, xi, scale, out);
}

bool CholeskyFactor::factor(const RPYMobility& mobility, int n, const double* x, bool single) {
    this->single = single;
    dim = 3 * n;
    if (single) {
        mobility.lowerMatrix(n, x, narrow);
        return choleskyLower(narrow, dim);
    }
    mobility.lowerMatrix(n, x, wide);
    return choleskyLower(wide, dim);
}

void CholeskyFactor::times(const double* xi, double scale, double* out) const {
    if (single)
        lowerTimes(narrow, dim, xi, scale, out);
    else
        lowerTimes(wide, dim, xi, scale, out);
}

KNOTMM_CLONES
bool KnotMM::choleskyLowerBuiltin(std::vector<double>& a, int n) {
    // Row-oriented Cholesky-Crout: L[i][j] = (A[i][j] - sum_k<j L[i][k] L[j][k]) / L[j][j];
    // the inner sums are contiguous dot products. The upper triangle is zeroed.
    for (int i = 0; i < n; i++) {
        double* li = &a[(size_t) i * n];
        for (int j = 0; j <= i; j++) {
            const double* lj = &a[(size_t) j * n];
            double s = li[j];
#pragma omp simd reduction(- : s)
            for (int k = 0; k < j; k++)
                s -= li[k] * lj[k];
            if (j < i)
                li[j] = s / lj[j];
            else {
                if (!positivePivot(s))  // not `s > 0` here: this file assumes finite math
                    return false;
                li[i] = std::sqrt(s);
            }
        }
        for (int j = i + 1; j < n; j++)
            li[j] = 0.0;
    }
    return true;
}
