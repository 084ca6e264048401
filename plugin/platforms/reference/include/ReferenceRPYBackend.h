#ifndef KNOTMM_REFERENCE_RPY_BACKEND_H_
#define KNOTMM_REFERENCE_RPY_BACKEND_H_

#include "RPYMobility.h"
#include "openmm/Vec3.h"
#include "knotmm/stepper/Backend.h"

#include <vector>

namespace OpenMM {
class System;
}

namespace KnotMM {

/** A vector of the Reference backend: host memory. */
class ReferenceVector : public StateVector {
public:
    explicit ReferenceVector(int size) : a(size, 0.0) {}
    std::vector<double> a;
};

/**
 * The stepper's backend on OpenMM's Reference and CPU platforms (the CPU platform shares the
 * Reference platform's PlatformData: positions and forces as std::vector<Vec3>, in double
 * precision). Velocities by RPYMobility's O(n^2) pair loop; noise by the dense Cholesky
 * factor (LAPACK's dpotrf when handed over) or by Lanczos (LanczosSqrt); vector operations as
 * plain loops in strict IEEE arithmetic.
 */
class ReferenceRPYBackend : public RPYBackend {
public:
    /**
     * `singleForces`: the platform computes forces in single precision (the CPU platform),
     * which a noise precision of "auto" follows (RPYIntegrator::setNoisePrecision).
     */
    ReferenceRPYBackend(const OpenMM::System& system, const RPYIntegrator& integrator, bool singleForces);
    /** A backend of `numBeads` beads that reads no System (a copy of a batch, ReferenceRPYBatch). */
    ReferenceRPYBackend(int numBeads, const RPYIntegrator& integrator, bool singleForces);
    int numBeads() const override { return n; }
    VectorPtr createVector() override { return VectorPtr(new ReferenceVector(3 * n)); }
    void applySettings(const RPYIntegrator& integrator) override;
    void getPositions(OpenMM::ContextImpl& context, StateVector& y) override;
    void setPositions(OpenMM::ContextImpl& context, const StateVector& y) override;
    bool holds(OpenMM::ContextImpl& context, const StateVector& y) override;
    void velocity(OpenMM::ContextImpl& context, const StateVector& y, StateVector& v) override;
    void groupEnergies(OpenMM::ContextImpl& context, const StateVector& at, const std::vector<int>& groups,
                       std::vector<double>& energies) override;
    void factorNoise(const StateVector& y) override;
    void applyNoise(double scale, const StateVector& z, StateVector& out) override;
    void normals(NoiseStream& stream, StateVector& out) override;
    void combine(StateVector& out, std::initializer_list<Term> terms) override;
    void copy(StateVector& out, const StateVector& in) override;
    void setZero(StateVector& out) override;
    bool equal(const StateVector& a, const StateVector& b) override;
    double norm(const StateVector& v) override;
    double maxBeadNorm(const StateVector& v) override;
    int firstNonFinite(const StateVector& v) override;
    TryCheck checkTry(const StateVector& err, const StateVector& y1) override {
        return TryCheck{maxBeadNorm(err), firstNonFinite(y1)};
    }
    void download(const StateVector& v, std::vector<double>& host) override;
    void upload(const std::vector<double>& host, StateVector& v) override;

protected:
    bool lanczosNoise() const { return lanczos; }
    /**
     * out = mu(y) F, F the forces of the beads, force[first + b] for bead b (kJ/mol/nm =
     * F0): the mobility half of velocity().
     */
    void mobilityTimes(const std::vector<double>& y, const std::vector<OpenMM::Vec3>& force, int first,
                       std::vector<double>& out);

private:
    /** The Context's bead positions = y, shifted to their centre of mass if `shift`. */
    void writePositions(OpenMM::ContextImpl& context, const std::vector<double>& y, bool shift) const;
    int n = 0;
    std::vector<int> beadParticle;  // bead -> particle index (virtual sites are not beads)
    bool hasVirtualSites = false;
    double diameter, mu0;
    int numThreads;
    RPYMobility mobility;
    bool lanczos = false;
    bool singleForces;          // the platform's forces are single precision
    bool singleFactor = false;  // the Cholesky factor in float, else in double
    double lanczosTolerance = 1e-6;
    LanczosSqrt lanczosSqrt;
    std::vector<double> xs, fs, vs, zs;  // scratch: structure-of-arrays copies
    CholeskyFactor cholesky;             // the noise factor of the last factorNoise
    std::vector<double> noiseAt;              // factorNoise's positions, structure of arrays
    std::vector<OpenMM::Vec3> beadForces;     // scratch: the beads' forces when sites sit among them
};

} // namespace KnotMM

#endif
