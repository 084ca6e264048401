#ifndef KNOTMM_RPY_MOBILITY_H_
#define KNOTMM_RPY_MOBILITY_H_

#include <memory>
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
     * as it was (the input choleskyLower needs).
     */
    void lowerMatrix(int n, const double* x, std::vector<double>& m) const;
private:
    void rows(int n, const double* x, const double* f, double* v, int begin, int end) const;
    double d, mu0;
    int numThreads;
    std::unique_ptr<OpenMM::ThreadPool> pool;  // OpenMM's persistent workers, when numThreads > 1
};

/**
 * In-place lower Cholesky factor of an SPD matrix (row-major n x n; only the lower triangle
 * is read, the upper one is zeroed); false if not SPD. The one place that decides how: LAPACK's dpotrf when a routine
 * was set with setCholeskyRoutine, else choleskyLowerBuiltin.
 */
bool choleskyLower(std::vector<double>& a, int n);

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

/** out = scale * L xi for a lower-triangular row-major n x n L (upper triangle ignored). */
void lowerTimes(const std::vector<double>& lower, int n, const double* xi, double scale, double* out);

} // namespace KnotMM

#endif
