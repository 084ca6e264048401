// Lanczos square root of the RPY mobility for Brownian noise (knotmm.dynamics.noise.lanczos_sqrt
// in C++), and the small symmetric tridiagonal eigen-problem it needs. Compiled with strict IEEE
// arithmetic (not RPYMobility.cpp's fast-math flags): the stopping rule compares small numbers;
// only the dot products' "omp simd" reductions are reassociated (vectorised).

#include "RPYMobility.h"

#include "knotmm/RPYStepFault.h"
#include "openmm/OpenMMException.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

using namespace KnotMM;

namespace {
// LAPACK dstev (Fortran convention: every argument by pointer); null until handed over.
typedef void (*StevRoutine)(char* jobz, int* n, double* d, double* e, double* z, int* ldz, double* work,
                            int* info);
std::atomic<StevRoutine> stevRoutine{nullptr};
} // namespace

void KnotMM::setTridiagonalEigenRoutine(unsigned long long address) {
    stevRoutine.store(reinterpret_cast<StevRoutine>(static_cast<uintptr_t>(address)));
}

unsigned long long KnotMM::getTridiagonalEigenRoutine() {
    return static_cast<unsigned long long>(reinterpret_cast<uintptr_t>(stevRoutine.load()));
}

bool KnotMM::tridiagonalEigen(const std::vector<double>& diag, const std::vector<double>& off, int k,
                              std::vector<double>& values, std::vector<double>& vectors) {
    StevRoutine stev = stevRoutine.load();
    if (stev == nullptr)
        throw OpenMM::OpenMMException("RPYIntegrator: Lanczos noise needs LAPACK's dstev, and none was "
                                      "handed over (knotmm.plugin.use_lapack_cholesky() hands over "
                                      "scipy's; or use the Cholesky noise)");
    thread_local std::vector<double> e, work;
    values.assign(diag.begin(), diag.begin() + k);
    e.assign(std::max(1, k - 1), 0.0);
    std::copy(off.begin(), off.begin() + (k - 1), e.begin());
    vectors.resize((size_t) k * k);
    work.resize(std::max(1, 2 * k - 2));
    char jobz = 'V';
    int size = k, ldz = k, info = 0;
    stev(&jobz, &size, values.data(), e.data(), vectors.data(), &ldz, work.data(), &info);
    return info == 0;
}

int LanczosSqrt::compute(const RPYMobility& mobility, int n, const double* x, const double* z, double tolerance,
                         double* out, int maxIter) {
    // one pointer captured: fits std::function's small buffer, so no allocation per call
    const struct {
        const RPYMobility& mobility;
        int n;
        const double* x;
    } product{mobility, n, x};
    const auto* p = &product;
    return compute([p](const double* v, double* w) { p->mobility.velocities(p->n, p->x, v, w); }, 3 * n, z,
                   tolerance, out, maxIter);
}

void LanczosSmallProblem::reset(int m) {
    alpha.assign(m, 0.0);
    beta.assign(m, 0.0);
    coeff.assign(m, 0.0);
    coeffOld.assign(m, 0.0);
    change = std::numeric_limits<double>::infinity();
    haveOld = false;
}

int LanczosSmallProblem::update(int k, int dim, double normZ, double tolerance) {
    // coefficients of the iterate in the basis: T^(1/2) e_1 = Q sqrt(Lambda) Q^T e_1
    const int size = k + 1;
    if (!tridiagonalEigen(alpha, beta, size, values, vectors))
        throw OpenMM::OpenMMException("Lanczos: the tridiagonal eigen-decomposition failed");
    double normC = 0.0, diff = 0.0;
    for (int i = 0; i < size; i++) {
        double c = 0.0;
        for (int j = 0; j < size; j++)
            c += vectors[(size_t) j * size + i] * std::sqrt(std::max(values[j], 0.0)) * vectors[(size_t) j * size];
        coeff[i] = c;
        normC += c * c;
        const double dc = c - (i < k ? coeffOld[i] : 0.0);
        diff += dc * dc;
    }
    // |y_k| and |y_k - y_(k-1)| from the coefficients (the basis is orthonormal)
    const double normY = normZ * std::sqrt(normC);
    if (haveOld) {
        change = normZ * std::sqrt(diff) / std::max(normY, 1e-300);
        if (change <= tolerance)
            return size;
    }
    double scale = 0.0;
    for (int i = 0; i < size; i++)
        scale = std::max(scale, std::fabs(alpha[i]));
    if (beta[k] <= 1e-13 * scale || size == dim)
        return size;  // invariant subspace: exact
    std::copy(coeff.begin(), coeff.begin() + size, coeffOld.begin());
    haveOld = true;
    return 0;
}

void LanczosSmallProblem::notConverged(int m, double tolerance) const {
    std::ostringstream msg;
    msg.precision(3);
    msg << "run.lanczos_tolerance = " << tolerance << " not reached: relative change " << change << " after " << m
        << " Lanczos iterations; raise run.lanczos_tolerance or use "
        << "run.noise = \"cholesky\"";
    throw RPYStepFault(RPYStepFault::LanczosNotConverged, msg.str());
}

int LanczosSqrt::compute(const MatrixTimes& times, int dim, const double* z, double tolerance, double* out,
                         int maxIter) {
    double normZ = 0.0;
    for (int i = 0; i < dim; i++)
        normZ += z[i] * z[i];
    normZ = std::sqrt(normZ);
    if (normZ == 0.0) {
        std::fill(out, out + dim, 0.0);
        return 0;
    }
    if (!(tolerance > 0.0))
        throw OpenMM::OpenMMException("lanczosTolerance: must be > 0");
    const int m = std::min(dim, maxIter);
    if (m < 1)
        throw OpenMM::OpenMMException("Lanczos: the iteration limit must be >= 1");
    basis.resize((size_t) m * dim);
    small.reset(m);
    std::vector<double>& alpha = small.alpha;
    std::vector<double>& beta = small.beta;
    w.resize(dim);
    proj.resize(m);
    for (int i = 0; i < dim; i++)
        basis[i] = z[i] / normZ;
    int used = 0;
    for (int k = 0; k < m && used == 0; k++) {
        const double* vk = &basis[(size_t) k * dim];
        times(vk, w.data());
        double a = 0.0;
#pragma omp simd reduction(+ : a)
        for (int i = 0; i < dim; i++)
            a += vk[i] * w[i];
        alpha[k] = a;
        for (int i = 0; i < dim; i++)
            w[i] -= a * vk[i];
        if (k > 0) {
            const double* vprev = &basis[(size_t) (k - 1) * dim];
            for (int i = 0; i < dim; i++)
                w[i] -= beta[k - 1] * vprev[i];
        }
        // full reorthogonalisation, classical Gram-Schmidt twice ("twice is enough")
        for (int pass = 0; pass < 2; pass++) {
            for (int j = 0; j <= k; j++) {
                const double* vj = &basis[(size_t) j * dim];
                double s = 0.0;
#pragma omp simd reduction(+ : s)
                for (int i = 0; i < dim; i++)
                    s += vj[i] * w[i];
                proj[j] = s;
            }
            for (int j = 0; j <= k; j++) {
                const double* vj = &basis[(size_t) j * dim];
                for (int i = 0; i < dim; i++)
                    w[i] -= proj[j] * vj[i];
            }
        }
        double b = 0.0;
#pragma omp simd reduction(+ : b)
        for (int i = 0; i < dim; i++)
            b += w[i] * w[i];
        beta[k] = std::sqrt(b);
        used = small.update(k, dim, normZ, tolerance);
        if (used == 0 && k + 1 < m) {
            double* vnext = &basis[(size_t) (k + 1) * dim];
            for (int i = 0; i < dim; i++)
                vnext[i] = w[i] / beta[k];
        }
    }
    if (used == 0)
        small.notConverged(m, tolerance);
    std::fill(out, out + dim, 0.0);
    for (int j = 0; j < used; j++) {
        const double c = normZ * small.coeff[j];
        const double* vj = &basis[(size_t) j * dim];
        for (int i = 0; i < dim; i++)
            out[i] += c * vj[i];
    }
    return used;
}
