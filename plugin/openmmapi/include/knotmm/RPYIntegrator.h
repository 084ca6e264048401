#ifndef KNOTMM_RPY_INTEGRATOR_H_
#define KNOTMM_RPY_INTEGRATOR_H_

// Overdamped (inertia-free) dynamics with the overlap-corrected Rotne-Prager-Yamakawa
// mobility:  dr_i/dt = sum_j mu_ij F_j  (+ sqrt(2 kT) B dW with B B^T = mu when kT > 0).
//
// Units are OpenMM's read as knotmm's model units: 1 nm = 1 bead diameter d, 1 kJ/mol =
// F0 d, 1 ps = tau_d. The formulas of every method are those of knotmm.dynamics.deterministic
// and knotmm.dynamics.brownian (the Python reference engine); the methods are listed in
// RPYMethods.h, their formulas live in plugin/stepper/, and each platform implements a small
// backend (plugin/stepper/include/knotmm/stepper/Backend.h). See plugin/README.md.

#include "openmm/Integrator.h"
#include "openmm/Kernel.h"
#include "openmm/Vec3.h"

#include <iosfwd>
#include <string>
#include <vector>

namespace KnotMM {

class RPYCopies;

class RPYIntegrator : public OpenMM::Integrator {
public:
    /**
     * @param stepSize     first (adaptive) or fixed step, in ps (= tau_d)
     * @param method       a name of the method table (RPYMethods.h): "euler", "heun",
     *                     "midpoint", "rk23", "rkc2", "euler_maruyama", "ito_heun",
     *                     "leimkuhler_matthews" or "ito_heun_adaptive"
     * @param errorTolerance  largest per-bead displacement error per step (adaptive), in nm
     *
     * The defaults (errorTolerance here, minimum and maximum step, Lanczos tolerance in the
     * constructor) are knotmm.dynamics.registry's DEFAULT_*, which a test holds them to.
     */
    explicit RPYIntegrator(double stepSize, const std::string& method = "rk23",
                           double errorTolerance = 1e-4);

    const std::string& getMethod() const { return method; }
    /**
     * Step with another method of the table from now on. Before the Context is created it is
     * the constructor's argument. In a Context the kernel is made again for it: the Context's
     * positions and time stay, everything else starts as in a new Context with this
     * integrator (counters at 0, no cached velocity, the noise stream seeded again, an
     * adaptive step clipped to getMaximumStepSize() as when a Context is created), so the
     * steps are those of an integrator built with `name` (knotmm's `auto` takes rkc2 so
     * after its stiffness probe, on the run's own Context). Throws for an unknown name, a
     * deterministic method while kT > 0, and an integrator of several copies in a Context.
     */
    void setMethod(const std::string& name);
    /** The step follows error control (rk23, rkc2, ito_heun_adaptive; RPYMethodInfo::adaptive). */
    bool isAdaptive() const;
    /**
     * Noise when kT > 0 (euler_maruyama, ito_heun, leimkuhler_matthews, ito_heun_adaptive;
     * RPYMethodInfo::stochastic).
     */
    bool isStochastic() const;

    double getErrorTolerance() const { return errorTolerance; }
    void setErrorTolerance(double tol);
    double getBeadDiameter() const { return beadDiameter; }
    void setBeadDiameter(double d);
    double getMobility() const { return mobility; }
    void setMobility(double mu0);
    /** Thermal energy kT in kJ/mol (= F0 d); 0 is deterministic. */
    double getThermalEnergy() const { return thermalEnergy; }
    void setThermalEnergy(double kT);
    /**
     * How stochastic methods draw the noise B xi (B B^T = mu): "cholesky" (the default; the
     * lower Cholesky factor of the dense 3n x 3n mobility, O(n^3)) or "lanczos" (the Krylov
     * approximation of mu^(1/2) xi from matrix-free products with the RPY pair loop,
     * O(k n^2) for k iterations; knotmm.dynamics.noise.lanczos_sqrt). Both draw 3n normals
     * per sample. A setting read at every step (not part of checkpoints).
     */
    const std::string& getNoiseMethod() const { return noiseMethod; }
    void setNoiseMethod(const std::string& method);
    /** Lanczos: relative change between successive iterates at which to stop (default 1e-6). */
    double getLanczosTolerance() const { return lanczosTolerance; }
    void setLanczosTolerance(double tol);
    /**
     * Precision of the Cholesky noise factor: "double", "single" (the matrix stored and
     * factorised in float, LAPACK's spotrf; B B^T = mu to about 1e-7 of its largest entry; the
     * products L z summed in double) or "auto" (the default: single where the platform's
     * forces are single precision, the CPU platform and a device platform in single or mixed
     * precision; double on Reference and a device platform in double). A setting read at every
     * step (not part of checkpoints); Lanczos noise is always double.
     */
    const std::string& getNoisePrecision() const { return noisePrecision; }
    void setNoisePrecision(const std::string& precision);
    int getRandomNumberSeed() const { return randomSeed; }
    void setRandomNumberSeed(int seed);
    double getMinimumStepSize() const { return minStepSize; }
    void setMinimumStepSize(double h);
    double getMaximumStepSize() const { return maxStepSize; }
    void setMaximumStepSize(double h);
    /** Threads of the RPY pair loop (rows are shared out; the result does not change). */
    int getNumThreads() const { return numThreads; }
    void setNumThreads(int n);
    /**
     * Start vector of rkc2's spectral-radius power iteration (one Vec3 per bead). Empty (the
     * default): a fixed pseudo-random vector. Lets a caller reproduce another engine's run.
     */
    void setSpectralRadiusStartVector(const std::vector<OpenMM::Vec3>& v);
    const std::vector<OpenMM::Vec3>& getSpectralRadiusStartVector() const { return rkcStart; }

    /**
     * Take `steps` accepted steps (fixed methods: of getStepSize()). A step that fails throws
     * RPYStepFault (RPYStepFault.h) and leaves the Context at the last good state.
     */
    void step(int steps) override;
    /**
     * Advance to `time` (ps) exactly: steps are never longer than what is left, and a time
     * within landingSlack(time) counts as reached. A time that is not finite, or earlier than
     * the Context's by more than the slack, throws OpenMMException.
     */
    void stepTo(double time);
    /**
     * As stepTo(time), but give the caller control back between steps: after each accepted
     * step, return once `maxSeconds` of wall-clock time have passed since the call (0: after
     * one step; +infinity: as stepTo). Returns true when `time` is reached, false when the
     * budget ran out first; the Context then holds a whole step boundary before `time`, and
     * the next call goes on with exactly the steps one stepTo(time) call would have taken (the
     * budget never changes a step, only where the calls end). A caller that must answer
     * signals or check the state while a stretch runs (knotmm's plugin engine) loops on it.
     * A `maxSeconds` that is negative or NaN throws OpenMMException, as stepTo's bad times.
     */
    bool stepToWithin(double time, double maxSeconds);

    /**
     * Potential energy of each force group in `groups` (each 0..31), in kJ/mol (= F0 d), at the
     * Context's current positions as the steps see them: beads shifted to their centre of
     * mass (translation changes only an external field's energy; for gravity add
     * g * n * z_com). One C++ call instead of one Context.getState per group. Nothing else
     * changes: the Context keeps its positions and forces, the integrator its cached velocity,
     * step size and noise stream, so the next step is the same with or without this call.
     */
    std::vector<double> getGroupEnergies(const std::vector<int>& groups);

    long long getNumForceEvaluations() const;
    long long getNumAcceptedSteps() const;
    long long getNumRejectedSteps() const;
    /** rkc2: stages of the last accepted step and the current spectral-radius estimate. */
    int getLastStages() const;
    double getSpectralRadius() const;
    /**
     * How many times the Context's positions were set from outside the integrator
     * (Context.setPositions, setState: OpenMM's stateChanged(State::Positions)). The stepper
     * keeps its state in double precision and reads the Context's positions again only when
     * this number has changed (and they are no longer the ones it wrote).
     */
    long long getPositionsVersion() const { return positionsVersion; }
    /**
     * The spectral radius of the velocity's Jacobian at the Context's positions, in 1/ps, as
     * rkc2 estimates it before its first step (power iteration from its start vector), for
     * any method; no step is taken and nothing else changes (knotmm's `auto` choice asks it
     * of the run's own Context).
     */
    double estimateSpectralRadius();

    /**
     * The integrator's state (step size and everything that decides the next steps: the
     * stepper's part of a Context checkpoint) as bytes, and its restoration: how a copy's
     * state moves between a batch (setNumCopies) and an integrator of that copy alone.
     */
    std::string getIntegratorState() const;
    void setIntegratorState(const std::string& state);

    // --- copies: K replicas of one system in one Context ---------------------------------
    /**
     * Integrate K copies of one system in one Context (set before the Context is created;
     * default 1): the System holds K copies of a system of n beads, copy k's beads being the
     * System's beads k n .. (k + 1) n - 1, its forces nothing between copies but what the
     * distance between them makes (the integrator keeps them apart, more than twice the
     * largest nonbonded cutoff). Each copy has its own positions, time, step size, step
     * control and noise stream, and its own block of the mobility; one force evaluation
     * serves every copy that needs one. Stepped by stepCopiesTo (step, stepTo and
     * getGroupEnergies refuse). Supported on the Reference and CPU platforms.
     */
    void setNumCopies(int copies);
    int getNumCopies() const { return numCopies; }
    /**
     * Whether the integrator keeps the copies apart in space (default true: each copy at
     * its own point of a grid, farther apart than the copies reach plus twice the largest
     * cutoff; a System with a plain NonbondedForce needs it). False: every copy is evaluated
     * at its own centre of mass, where a copy alone is, all copies in the same place; the
     * System must then keep them from interacting (a CustomNonbondedForce with one
     * interaction group per copy), and a copy's forces are those of the copy alone, whatever
     * the others do. Set before the Context is created.
     */
    void setCopiesApart(bool apart);
    bool getCopiesApart() const { return copiesApart; }
    /** RPYCopies::stepTo: every copy towards its own target (ps); true when all are there. */
    bool stepCopiesTo(const std::vector<double>& targets, double maxSeconds);
    /** Copy k's bead positions, 3n numbers, bead-major, in nm. */
    std::vector<double> getCopyPositions(int copy) const;
    void setCopyPositions(int copy, const std::vector<double>& positions);
    double getCopyTime(int copy) const;
    void setCopyTime(int copy, double time);
    /** Copy k's state in getIntegratorState()'s layout. */
    std::string getCopyState(int copy) const;
    void setCopyState(int copy, const std::string& state);
    /** Copy k's fault: kind ("" for none) and message; clearCopyFault lets it step again. */
    std::string getCopyFaultKind(int copy) const;
    std::string getCopyFaultMessage(int copy) const;
    void clearCopyFault(int copy);
    /** Centre-to-centre distance of neighbouring copies in the Context, in nm (0: not apart). */
    double getCopySpacing() const;
    /** The integrator's part of a checkpoint: its layout tag and the step size (ps). */
    static void writeStateHeader(std::ostream& stream, double stepSize);
    /** Reads writeStateHeader's part; returns the step size. Throws for another layout. */
    static double readStateHeader(std::istream& stream);

protected:
    void initialize(OpenMM::ContextImpl& context) override;
    void cleanup() override;
    std::vector<std::string> getKernelNames() override;
    double computeKineticEnergy() override { return 0.0; }
    bool kineticEnergyRequiresForce() const override { return false; }
    void createCheckpoint(std::ostream& stream) const override;
    void loadCheckpoint(std::istream& stream) override;
    /** OpenMM's signal that the Context's state was set from outside (getPositionsVersion). */
    void stateChanged(OpenMM::State::DataType changed) override;

private:
    void checkInitialized() const;
    RPYCopies& copies() const;
    void checkSingle(const char* what) const;
    void checkTarget(double time) const;
    void takeStep(double targetTime);
    std::string method, noiseMethod, noisePrecision;
    double lanczosTolerance;
    double errorTolerance, beadDiameter, mobility, thermalEnergy, minStepSize, maxStepSize;
    int randomSeed, numThreads, numCopies = 1;
    bool copiesApart = true;
    std::vector<OpenMM::Vec3> rkcStart;
    OpenMM::Kernel kernel;
    bool kernelReady = false;
    long long positionsVersion = 0;
};

} // namespace KnotMM

#endif
