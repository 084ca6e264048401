#ifndef KNOTMM_STEPPER_BACKEND_H_
#define KNOTMM_STEPPER_BACKEND_H_

// What a platform implements for the stepper: the forces of the Context turned into
// velocities v = mu(y) F(y), the noise B(y) xi with B B^T = mu(y), and the few vector
// operations the methods are written in, all on that platform's memory. The stepper
// (Stepper.h) holds every method's formulas, step control, landing and the checkpoint layout,
// and never touches a vector's numbers itself; so a CUDA or OpenCL version of the plugin is a
// new Backend (plugin/platforms/<name>/) and nothing else. The Reference backend
// (platforms/reference/ReferenceRPYBackend) serves OpenMM's Reference and CPU platforms.
//
// Vectors hold 3n numbers for n beads, bead-major (x0, y0, z0, x1, ...), in nm (= d) or
// nm/ps (= d/tau_d). Beads are the System's particles that are not virtual sites.

#include <initializer_list>
#include <memory>
#include <vector>

namespace OpenMM {
class ContextImpl;
}

namespace KnotMM {

class NoiseStream;
class RPYIntegrator;

/** 3n numbers in a backend's memory; only the backend that made it reads them. */
class StateVector {
public:
    virtual ~StateVector() {}
};
typedef std::unique_ptr<StateVector> VectorPtr;

/** One term of RPYBackend::combine: c * v, or v / c when `divide`. */
struct Term {
    double c;
    const StateVector* v;
    bool divide;
};
inline Term times(double c, const StateVector& v) { return Term{c, &v, false}; }
inline Term over(const StateVector& v, double c) { return Term{c, &v, true}; }

class RPYBackend {
public:
    virtual ~RPYBackend() {}
    virtual int numBeads() const = 0;
    /** A new vector of 3n zeros. */
    virtual VectorPtr createVector() = 0;

    /** Settings that may change between steps: threads, noise method and tolerance. */
    virtual void applySettings(const RPYIntegrator& integrator) = 0;

    // --- the Context ---------------------------------------------------------------------
    // The stepper owns the state y in double precision (its own vector); the Context's
    // positions are what it writes after each step (setPositions) and the scratch of each
    // force evaluation (velocity). It reads them back (getPositions) only at the start and
    // when they were set from outside (RPYIntegrator::getPositionsVersion) to something else
    // than what it wrote (holds).
    /** y = the beads' positions in the Context. */
    virtual void getPositions(OpenMM::ContextImpl& context, StateVector& y) = 0;
    /** The Context's bead positions = y (virtual sites placed from them). */
    virtual void setPositions(OpenMM::ContextImpl& context, const StateVector& y) = 0;
    /**
     * True when the Context's bead positions are what setPositions(y) leaves there: y itself
     * in double precision, y rounded as the Context stores it otherwise (mixed: a float and
     * the float of the remainder; single: a float).
     */
    virtual bool holds(OpenMM::ContextImpl& context, const StateVector& y) = 0;
    /**
     * v = mu(y) F, F the Context's forces (the integration force groups) with the beads at y
     * shifted to their centre of mass: translation leaves internal forces as they are and
     * keeps single-precision platforms precise however far the chain has fallen. Leaves the
     * Context's positions at the shifted y.
     */
    virtual void velocity(OpenMM::ContextImpl& context, const StateVector& y, StateVector& v) = 0;
    /**
     * Energy of each force group in `groups` with the beads at `at` shifted as velocity()
     * shifts them; the Context is left exactly as it was (positions, forces, last force groups).
     */
    virtual void groupEnergies(OpenMM::ContextImpl& context, const StateVector& at, const std::vector<int>& groups,
                               std::vector<double>& energies) = 0;

    // --- noise ---------------------------------------------------------------------------
    /**
     * Prepare B(y), B B^T = mu(y), for applyNoise (Cholesky: factorise the mobility; Lanczos:
     * remember y). Throws RPYStepFault (NotPositiveDefinite) when it cannot.
     */
    virtual void factorNoise(const StateVector& y) = 0;
    /**
     * out = scale B z with the B of the last factorNoise (Cholesky or Lanczos, applySettings).
     * Throws RPYStepFault (LanczosNotConverged) when it cannot.
     */
    virtual void applyNoise(double scale, const StateVector& z, StateVector& out) = 0;
    /**
     * out = the next draw of 3n standard normals from `stream`, bead-major: a counter-based
     * stream's draw made where the vectors live (philox::normals, the same numbers on every
     * platform up to the rounding of its log, sqrt, cos and sin), a sequential one's on the host.
     */
    virtual void normals(NoiseStream& stream, StateVector& out) = 0;

    // --- vector operations -----------------------------------------------------------------
    /**
     * out_i = t_0 + t_1 + ... (added left to right), t_k = c_k v_k,i or v_k,i / c_k. `out` may
     * be one of the inputs. The order of operations is part of the contract: it is what makes
     * a platform's trajectories the same bit for bit from one version to the next.
     */
    virtual void combine(StateVector& out, std::initializer_list<Term> terms) = 0;
    virtual void copy(StateVector& out, const StateVector& in) = 0;
    virtual void setZero(StateVector& out) = 0;
    /** Element by element ==, both taken as the Context stores positions (see holds). */
    virtual bool equal(const StateVector& a, const StateVector& b) = 0;
    /** sqrt(sum_i v_i^2). */
    virtual double norm(const StateVector& v) = 0;
    /** max over beads of sqrt(vx^2 + vy^2 + vz^2); +infinity if any number is not finite. */
    virtual double maxBeadNorm(const StateVector& v) = 0;
    /** The index of the first number that is not finite, or -1. */
    virtual int firstNonFinite(const StateVector& v) = 0;
    /** What the end of an adaptive method's try needs on the host (checkTry). */
    struct TryCheck {
        double errorNorm;  // maxBeadNorm(err)
        int nonFinite;     // firstNonFinite(y1)
    };
    /** maxBeadNorm(err) and firstNonFinite(y1) together: one download on a device. */
    virtual TryCheck checkTry(const StateVector& err, const StateVector& y1) = 0;
    /** To and from the host (checkpoints, start vectors): 3n numbers, bead-major. */
    virtual void download(const StateVector& v, std::vector<double>& host) = 0;
    virtual void upload(const std::vector<double>& host, StateVector& v) = 0;
};

} // namespace KnotMM

#endif
