#ifndef KNOTMM_RPY_MOBILITY_H_
#define KNOTMM_RPY_MOBILITY_H_

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace OpenMM {
class ThreadPool;
}

namespace KnotMM {

/**
 * Overlap-corrected RPY mobility of equal beads (diameter d, single-bead mobility mu0):
 *   mu_ii = mu0 I,
 *   r >= d: mu_ij = mu0 3d/(8r) [(1 + d^2/(6r^2)) I + (1 - d^2/(2r^2)) rhat rhat],
 *   r <  d: mu_ij = mu0 [(1 - 9r/(16d)) I + 3r/(16d) rhat rhat].
 * Coordinates are structure-of-arrays: x[3*n] = (x_0..x_{n-1}, y_0.., z_0..).
 */
class RPYMobility {
public:
    RPYMobility(double diameter, double mu0, int numThreads);
    ~RPYMobility();
    RPYMobility(RPYMobility&&) noexcept;
    RPYMobility& operator=(RPYMobility&&) noexcept;
    /** v = mu(x) f, matrix-free, O(n^2). All arrays SoA of length 3n. */
    void velocities(int n, const double* x, const double* f, double* v) const;
    /**
     * Lower triangle (diagonal included) of the dense 3n x 3n mobility, bead-major (x0, y0,
     * z0, x1, ...), row-major storage; m is resized to 3n x 3n and its upper triangle is left
     * as it was (the input choleskyLower needs). Computed in double precision and stored as
     * Real (double, or float for a single-precision noise factor).
     */
    template <class Real>
    void lowerMatrix(int n, const double* x, std::vector<Real>& m) const;
private:
    void rows(int n, const double* x, const double* f, double* v, int begin, int end) const;
    double d, mu0;
    int numThreads;
    std::unique_ptr<OpenMM::ThreadPool> pool;  // OpenMM's persistent workers, when numThreads > 1
};

/**
 * In-place lower Cholesky factor of an SPD matrix (row-major n x n; only the lower triangle
 * is read, the upper one is zeroed); false if not SPD. The one place that decides how:
 * LAPACK's dpotrf when a routine was set with setCholeskyRoutine, else choleskyLowerBuiltin.
 */
bool choleskyLower(std::vector<double>& a, int n);
/**
 * The same in single precision: LAPACK's spotrf when a routine was set with
 * setSingleCholeskyRoutine, else the built-in routine in double precision, rounded.
 */
bool choleskyLower(std::vector<float>& a, int n);

/**
 * Whether the Cholesky noise factor is made in single precision, for
 * RPYIntegrator::getNoisePrecision() on a platform whose forces are single precision or not.
 */
inline bool usesSingleFactor(const std::string& precision, bool singleForces) {
    return precision == "single" || (precision == "auto" && singleForces);
}

/**
 * True if `s` is a number > 0 (false for NaN). Defined in a file compiled with strict IEEE
 * arithmetic (RPYStrict.cpp), so that the fast-math pair-loop file can call it: there the
 * compiler assumes finite math and would let a NaN pass a plain `s > 0` test.
 */
bool positivePivot(double s);

/** The built-in unblocked Cholesky-Crout (no LAPACK): same contract as choleskyLower. */
bool choleskyLowerBuiltin(std::vector<double>& a, int n);

/**
 * Use LAPACK's dpotrf at `address` for choleskyLower: a C function
 * `void dpotrf(char* uplo, int* n, double* a, int* lda, int* info)` (32-bit int, Fortran
 * calling convention), as scipy.linalg.cython_lapack exports it (knotmm.plugin hands it over).
 * 0 goes back to the built-in routine. Process-wide; set it before steps are taken.
 */
void setCholeskyRoutine(unsigned long long address);
/** The dpotrf address in use, or 0 for the built-in routine. */
unsigned long long getCholeskyRoutine();
/**
 * Use LAPACK's spotrf at `address` for the single-precision choleskyLower (the same
 * signature with float*), as scipy.linalg.cython_lapack exports it. 0: the built-in routine.
 */
void setSingleCholeskyRoutine(unsigned long long address);
/** The spotrf address in use, or 0. */
unsigned long long getSingleCholeskyRoutine();

/** out = scale * L xi for a lower-triangular row-major n x n L (upper triangle ignored). */
void lowerTimes(const std::vector<double>& lower, int n, const double* xi, double scale, double* out);
/** The same with a single-precision L; the sums in double precision. */
void lowerTimes(const std::vector<float>& lower, int n, const double* xi, double scale, double* out);

/**
 * The dense Cholesky noise factor L (L L^T = mu) of a backend, on the host, in double or in
 * single precision (RPYIntegrator::setNoisePrecision; usesSingleFactor).
 */
class CholeskyFactor {
public:
    /** L of mu(x) (x structure of arrays, 3n), in float if `single`; false if not SPD. */
    bool factor(const RPYMobility& mobility, int n, const double* x, bool single);
    /** out = scale L xi, 3n numbers (the sums in double). */
    void times(const double* xi, double scale, double* out) const;

private:
    bool single = false;
    int dim = 0;
    std::vector<double> wide;   // the matrix, then its factor, in double
    std::vector<float> narrow;  // the same in float
};

/**
 * Eigen-decomposition of the symmetric tridiagonal k x k matrix with diagonal `diag` (k numbers)
 * and off-diagonal `off` (k - 1 numbers): eigenvalues into `values` (k), eigenvectors as the
 * columns of the column-major `vectors` (k x k), by LAPACK's dstev, set with
 * setTridiagonalEigenRoutine (OpenMM::OpenMMException if none was). False if the iteration
 * failed.
 */
bool tridiagonalEigen(const std::vector<double>& diag, const std::vector<double>& off, int k,
                      std::vector<double>& values, std::vector<double>& vectors);

/**
 * Use LAPACK's dstev at `address` for tridiagonalEigen: `void dstev(char* jobz, int* n,
 * double* d, double* e, double* z, int* ldz, double* work, int* info)`, as
 * scipy.linalg.cython_lapack exports it. 0: none (Lanczos noise is then refused). Process-wide.
 */
void setTridiagonalEigenRoutine(unsigned long long address);
/** The dstev address in use, or 0 for none. */
unsigned long long getTridiagonalEigenRoutine();

/** Default iteration limit of LanczosSqrt (knotmm.dynamics.noise.LANCZOS_MAX_ITER). */
const int LANCZOS_MAX_ITER = 200;

/**
 * The small problem of a Lanczos iteration, on the host for every platform: after iteration
 * k (alpha[0..k] = v_j . mu v_j, beta[0..k] the norms of the orthogonalised residuals), the
 * coefficients of y_k = |z| V_k T_k^(1/2) e_1 in the basis (coeff, from tridiagonalEigen) and
 * the stopping rule of LanczosSqrt. A device backend runs the Krylov vectors on the device and
 * this here.
 */
class LanczosSmallProblem {
public:
    /** Start an iteration of at most m steps. */
    void reset(int m);
    /**
     * After iteration k (alpha[k], beta[k] set) of vectors of `dim` numbers, z of norm normZ:
     * coeff[0..k]; returns the number of basis vectors of the result when converged
     * (|y_k - y_(k-1)| <= tolerance |y_k|) or exact (invariant subspace, or k + 1 = dim), 0
     * to go on (then v_(k+1) = w / beta[k]).
     */
    int update(int k, int dim, double normZ, double tolerance);
    /** Throws RPYStepFault (LanczosNotConverged) after m iterations without convergence. */
    [[noreturn]] void notConverged(int m, double tolerance) const;
    std::vector<double> alpha, beta, coeff;

private:
    std::vector<double> values, vectors, coeffOld;
    double change = 0.0;
    bool haveOld = false;
};

/**
 * Krylov approximation of mu^(1/2) z, matrix-free (knotmm.dynamics.noise.lanczos_sqrt):
 * Lanczos with full reorthogonalisation (classical Gram-Schmidt, twice) builds V_k and the
 * tridiagonal T_k = V_k^T mu V_k; the iterate is y_k = |z| V_k T_k^(1/2) e_1, T_k^(1/2) from
 * its eigen-decomposition (tridiagonalEigen). It stops when |y_k - y_(k-1)| <= tolerance |y_k|,
 * or when the Krylov space is invariant (beta_k <= 1e-13 max|alpha|, or k = 3n): then y_k is
 * exact up to rounding. The workspace is kept between calls.
 */
class LanczosSqrt {
public:
    /** w = M v for the symmetric positive definite M whose square root is wanted (dim numbers each). */
    typedef std::function<void(const double* v, double* w)> MatrixTimes;
    /**
     * out = mu(x)^(1/2) z (SoA arrays of 3n numbers, as RPYMobility). Returns the iterations
     * (matrix-vector products) used; throws OpenMM::OpenMMException if min(maxIter, 3n)
     * iterations do not reach the tolerance, or the eigen-decomposition fails.
     */
    int compute(const RPYMobility& mobility, int n, const double* x, const double* z, double tolerance,
                double* out, int maxIter = LANCZOS_MAX_ITER);
    /**
     * out = M^(1/2) z for vectors of `dim` numbers, M given by its products (`times`, in
     * whatever layout z has: a device backend runs them on the device). The same iteration,
     * stopping rule and faults as above, which calls this with RPYMobility::velocities.
     */
    int compute(const MatrixTimes& times, int dim, const double* z, double tolerance, double* out,
                int maxIter = LANCZOS_MAX_ITER);
private:
    std::vector<double> basis, w, proj;
    LanczosSmallProblem small;
};

} // namespace KnotMM

#endif
