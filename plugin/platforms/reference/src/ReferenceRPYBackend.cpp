#include "ReferenceRPYBackend.h"

#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "knotmm/stepper/NoiseStream.h"
#include "openmm/System.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/reference/ReferencePlatform.h"

#include <algorithm>
#include <cmath>
#include <limits>

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

namespace {

ReferencePlatform::PlatformData& platformData(ContextImpl& context) {
    return *static_cast<ReferencePlatform::PlatformData*>(context.getPlatformData());
}

inline vector<double>& data(StateVector& v) { return static_cast<ReferenceVector&>(v).a; }
inline const vector<double>& data(const StateVector& v) { return static_cast<const ReferenceVector&>(v).a; }

} // namespace

ReferenceRPYBackend::ReferenceRPYBackend(const System& system, const RPYIntegrator& integrator, bool singleForces)
    : diameter(integrator.getBeadDiameter()), mu0(integrator.getMobility()),
      numThreads(integrator.getNumThreads()), mobility(diameter, mu0, numThreads), singleForces(singleForces) {
    for (int i = 0; i < system.getNumParticles(); i++) {
        if (system.isVirtualSite(i))
            hasVirtualSites = true;
        else
            beadParticle.push_back(i);
    }
    n = beadParticle.size();
    for (vector<double>* v : {&xs, &fs, &vs, &zs})
        v->assign(3 * n, 0.0);
    applySettings(integrator);
}

ReferenceRPYBackend::ReferenceRPYBackend(int numBeads, const RPYIntegrator& integrator, bool singleForces)
    : diameter(integrator.getBeadDiameter()), mu0(integrator.getMobility()),
      numThreads(integrator.getNumThreads()), mobility(diameter, mu0, numThreads), singleForces(singleForces) {
    n = numBeads;
    for (int b = 0; b < n; b++)
        beadParticle.push_back(b);
    for (vector<double>* v : {&xs, &fs, &vs, &zs})
        v->assign(3 * n, 0.0);
    applySettings(integrator);
}

void ReferenceRPYBackend::applySettings(const RPYIntegrator& integrator) {
    lanczos = integrator.getNoiseMethod() == "lanczos";
    lanczosTolerance = integrator.getLanczosTolerance();
    singleFactor = usesSingleFactor(integrator.getNoisePrecision(), singleForces);
    if (integrator.getNumThreads() != numThreads) {
        numThreads = integrator.getNumThreads();
        mobility = RPYMobility(diameter, mu0, numThreads);
    }
}

// --- the Context -------------------------------------------------------------------------------

void ReferenceRPYBackend::getPositions(ContextImpl& context, StateVector& y) {
    const vector<Vec3>& pos = *platformData(context).positions;
    vector<double>& out = data(y);
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            out[3 * b + k] = pos[beadParticle[b]][k];
}

void ReferenceRPYBackend::writePositions(ContextImpl& context, const vector<double>& in, bool shift) const {
    vector<Vec3>& pos = *platformData(context).positions;
    double com[3] = {0.0, 0.0, 0.0};
    if (shift) {
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                com[k] += in[3 * b + k];
        for (int k = 0; k < 3; k++)
            com[k] /= n;
    }
    for (int b = 0; b < n; b++)
        pos[beadParticle[b]] = Vec3(in[3 * b] - com[0], in[3 * b + 1] - com[1], in[3 * b + 2] - com[2]);
    if (hasVirtualSites)
        context.computeVirtualSites();
}

void ReferenceRPYBackend::setPositions(ContextImpl& context, const StateVector& y) {
    writePositions(context, data(y), false);
}

bool ReferenceRPYBackend::holds(ContextImpl& context, const StateVector& y) {
    const vector<Vec3>& pos = *platformData(context).positions;
    const vector<double>& in = data(y);
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            if (pos[beadParticle[b]][k] != in[3 * b + k])
                return false;
    return true;
}

void ReferenceRPYBackend::velocity(ContextImpl& context, const StateVector& y, StateVector& v) {
    writePositions(context, data(y), true);
    context.calcForcesAndEnergy(true, false, context.getIntegrator().getIntegrationForceGroups());
    const vector<Vec3>& force = *platformData(context).forces;
    if (beadParticle.empty() || beadParticle.back() == n - 1)  // the beads are particles 0 .. n-1
        mobilityTimes(data(y), force, 0, data(v));
    else {
        beadForces.resize(n);
        for (int b = 0; b < n; b++)
            beadForces[b] = force[beadParticle[b]];
        mobilityTimes(data(y), beadForces, 0, data(v));
    }
}

void ReferenceRPYBackend::mobilityTimes(const vector<double>& yy, const vector<Vec3>& force, int first,
                                        vector<double>& out) {
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++) {
            xs[k * n + b] = yy[3 * b + k];
            fs[k * n + b] = force[first + b][k];
        }
    mobility.velocities(n, xs.data(), fs.data(), vs.data());
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            out[3 * b + k] = vs[k * n + b];
}

void ReferenceRPYBackend::groupEnergies(ContextImpl& context, const StateVector& at, const vector<int>& groups,
                                        vector<double>& energies) {
    // At the positions the steps evaluate forces at (writePositions with the shift, bit for
    // bit), one energy-only evaluation per group, then the Context exactly as it was.
    ReferencePlatform::PlatformData& platform = platformData(context);
    const vector<Vec3> savedPositions = *platform.positions;
    const vector<Vec3> savedForces = *platform.forces;
    const int savedGroups = context.getLastForceGroups();
    energies.assign(groups.size(), 0.0);
    try {
        writePositions(context, data(at), true);
        for (size_t i = 0; i < groups.size(); i++)
            energies[i] = context.calcForcesAndEnergy(false, true, 1 << groups[i]);
    }
    catch (...) {
        *platform.positions = savedPositions;
        *platform.forces = savedForces;
        context.getLastForceGroups() = savedGroups;
        throw;
    }
    *platform.positions = savedPositions;
    *platform.forces = savedForces;
    context.getLastForceGroups() = savedGroups;
}

// --- noise -------------------------------------------------------------------------------------

void ReferenceRPYBackend::factorNoise(const StateVector& y) {
    const vector<double>& yy = data(y);
    noiseAt.resize(3 * n);
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            noiseAt[k * n + b] = yy[3 * b + k];
    if (lanczos)
        return;  // matrix-free: applyNoise runs the Krylov iteration at noiseAt
    // exact: the dense Cholesky factor of the 3n x 3n mobility
    if (!cholesky.factor(mobility, n, noiseAt.data(), singleFactor))
        throw RPYStepFault(RPYStepFault::NotPositiveDefinite,
                           "RPYIntegrator: the RPY mobility is not positive definite at these "
                           "positions (two beads at the same point?)");
}

void ReferenceRPYBackend::applyNoise(double scale, const StateVector& z, StateVector& outVector) {
    const vector<double>& zz = data(z);
    vector<double>& out = data(outVector);
    if (!lanczos) {
        cholesky.times(zz.data(), scale, out.data());
        return;
    }
    // B z = mu^(1/2) z by Lanczos, matrix-free (the pair loop of the velocities)
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            zs[k * n + b] = zz[3 * b + k];
    lanczosSqrt.compute(mobility, n, noiseAt.data(), zs.data(), lanczosTolerance, vs.data());
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            out[3 * b + k] = scale * vs[k * n + b];
}

void ReferenceRPYBackend::normals(NoiseStream& stream, StateVector& outVector) {
    std::vector<double>& out = data(outVector);
    stream.fill(out.data(), (int) out.size());
}

// --- vector operations ---------------------------------------------------------------------------

void ReferenceRPYBackend::combine(StateVector& outVector, std::initializer_list<Term> terms) {
    // out_i = t_0 + t_1 + ... left to right: the order the formulas are written in
    const int m = 3 * n, count = (int) terms.size();
    const double* v[8];
    double c[8];
    bool divide[8];
    if (count < 1 || count > 8)
        throw OpenMM::OpenMMException("ReferenceRPYBackend::combine: 1 to 8 terms");
    int k = 0;
    for (const Term& t : terms) {
        v[k] = data(*t.v).data();
        c[k] = t.c;
        divide[k] = t.divide;
        k++;
    }
    double* out = data(outVector).data();
    for (int i = 0; i < m; i++) {
        double acc = divide[0] ? v[0][i] / c[0] : c[0] * v[0][i];
        for (int j = 1; j < count; j++)
            acc = acc + (divide[j] ? v[j][i] / c[j] : c[j] * v[j][i]);
        out[i] = acc;
    }
}

void ReferenceRPYBackend::copy(StateVector& out, const StateVector& in) { data(out) = data(in); }

void ReferenceRPYBackend::setZero(StateVector& out) { std::fill(data(out).begin(), data(out).end(), 0.0); }

bool ReferenceRPYBackend::equal(const StateVector& a, const StateVector& b) { return data(a) == data(b); }

double ReferenceRPYBackend::norm(const StateVector& vector) {
    const std::vector<double>& v = data(vector);
    double sum = 0.0;
    for (double x : v)
        sum += x * x;
    return std::sqrt(sum);
}

double ReferenceRPYBackend::maxBeadNorm(const StateVector& vector) {
    const std::vector<double>& e = data(vector);
    double worst = 0.0;
    bool finite = true;
    for (int b = 0; b < n; b++) {
        const double s = e[3 * b] * e[3 * b] + e[3 * b + 1] * e[3 * b + 1] + e[3 * b + 2] * e[3 * b + 2];
        finite = finite && std::isfinite(s);
        worst = std::max(worst, s);
    }
    return finite ? std::sqrt(worst) : std::numeric_limits<double>::infinity();
}

int ReferenceRPYBackend::firstNonFinite(const StateVector& vector) {
    const std::vector<double>& v = data(vector);
    for (int i = 0; i < (int) v.size(); i++)
        if (!std::isfinite(v[i]))
            return i;
    return -1;
}

void ReferenceRPYBackend::download(const StateVector& v, std::vector<double>& host) { host = data(v); }

void ReferenceRPYBackend::upload(const std::vector<double>& host, StateVector& v) { data(v) = host; }
