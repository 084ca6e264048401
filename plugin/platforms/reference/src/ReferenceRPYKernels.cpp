#include "ReferenceRPYKernels.h"

#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/reference/ReferencePlatform.h"

#include <algorithm>
#include <cmath>
#include <istream>
#include <limits>
#include <ostream>
#include <random>
#include <sstream>

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

// ---------------------------------------------------------------------------------------------
// NoiseStream

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void NoiseStream::seed(uint64_t value) {
    // splitmix64 fills the xoshiro state (never all zero)
    for (auto& word : s) {
        value += 0x9e3779b97f4a7c15ULL;
        uint64_t z = value;
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        word = z ^ (z >> 31);
    }
    haveSpare = false;
    spare = 0.0;
}

uint64_t NoiseStream::next() {
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double NoiseStream::uniform() { return (next() >> 11) * 0x1.0p-53; }

double NoiseStream::normal() {
    if (haveSpare) {
        haveSpare = false;
        return spare;
    }
    double u, v, q;
    do {
        u = 2.0 * uniform() - 1.0;
        v = 2.0 * uniform() - 1.0;
        q = u * u + v * v;
    } while (q >= 1.0 || q == 0.0);
    const double scale = std::sqrt(-2.0 * std::log(q) / q);
    spare = v * scale;
    haveSpare = true;
    return u * scale;
}

void NoiseStream::write(std::ostream& stream) const {
    stream.write((const char*) s, sizeof(s));
    stream.write((const char*) &haveSpare, sizeof(bool));
    stream.write((const char*) &spare, sizeof(double));
}

void NoiseStream::read(std::istream& stream) {
    stream.read((char*) s, sizeof(s));
    stream.read((char*) &haveSpare, sizeof(bool));
    stream.read((char*) &spare, sizeof(double));
}

// ---------------------------------------------------------------------------------------------
// helpers

namespace {

ReferencePlatform::PlatformData& platformData(ContextImpl& context) {
    return *static_cast<ReferencePlatform::PlatformData*>(context.getPlatformData());
}

template <class T>
void put(std::ostream& stream, const T& value) {
    stream.write((const char*) &value, sizeof(T));
}

template <class T>
void get(std::istream& stream, T& value) {
    stream.read((char*) &value, sizeof(T));
}

void putVec(std::ostream& stream, const vector<double>& v) {
    long long size = v.size();
    put(stream, size);
    if (size > 0)
        stream.write((const char*) v.data(), sizeof(double) * size);
}

void getVec(std::istream& stream, vector<double>& v) {
    long long size = 0;
    get(stream, size);
    v.resize(size);
    if (size > 0)
        stream.read((char*) v.data(), sizeof(double) * size);
}

std::string fmt(double x) {
    std::ostringstream s;
    s.precision(6);
    s << x;
    return s.str();
}

// 3: leimkuhler_matthews's held kick; 2 (no kick) still loads.
const int KERNEL_CHECKPOINT_VERSION = 3;

} // namespace

// ---------------------------------------------------------------------------------------------
// setup, positions, velocities

void ReferenceIntegrateRPYStepKernel::initialize(const System& system, const RPYIntegrator& integrator) {
    const std::string& name = integrator.getMethod();
    const char* names[] = {"euler", "heun", "midpoint", "rk23", "rkc2", "euler_maruyama", "ito_heun",
                           "leimkuhler_matthews"};
    const Method methods[] = {EULER, HEUN, MIDPOINT, RK23, RKC2, EULER_MARUYAMA, ITO_HEUN, LEIMKUHLER_MATTHEWS};
    bool found = false;
    for (int i = 0; i < 8; i++)
        if (name == names[i]) {
            method = methods[i];
            found = true;
        }
    if (!found)
        throw OpenMMException("RPYIntegrator: unknown method '" + name + "'");
    beadParticle.clear();
    hasVirtualSites = false;
    for (int i = 0; i < system.getNumParticles(); i++) {
        if (system.isVirtualSite(i))
            hasVirtualSites = true;
        else
            beadParticle.push_back(i);
    }
    if (system.usesPeriodicBoundaryConditions())
        throw OpenMMException("RPYIntegrator: the System is periodic, but the RPY mobility here is "
                              "the free-space one (no periodic images); use non-periodic forces");
    if (system.getNumConstraints() > 0)
        throw OpenMMException("RPYIntegrator: the System has constraints, which overdamped RPY "
                              "dynamics does not support; use stiff bonds instead");
    n = beadParticle.size();
    if (n == 0)
        throw OpenMMException("RPYIntegrator: the System has no particles to move");
    kT = integrator.getThermalEnergy();
    numThreads = integrator.getNumThreads();
    mobility = RPYMobility(integrator.getBeadDiameter(), integrator.getMobility(), numThreads);
    int seed = integrator.getRandomNumberSeed();
    noise.seed(seed != 0 ? (uint64_t) (uint32_t) seed : (uint64_t) std::random_device()() << 32 ^ std::random_device()());
    rkcStart = integrator.getSpectralRadiusStartVector();
    lanczos = integrator.getNoiseMethod() == "lanczos";
    lanczosTolerance = integrator.getLanczosTolerance();
    for (Vec* v : {&y, &k1, &k2, &k3, &k4, &y1, &ytmp, &err, &w, &xi, &xs, &fs, &vs, &zs})
        v->assign(3 * n, 0.0);
}

void ReferenceIntegrateRPYStepKernel::invalidateCache() {
    haveK1 = false;
    haveRho = false;  // as knotmm's RKC2.reset(): re-estimate after outside changes
}

void ReferenceIntegrateRPYStepKernel::readPositions(ContextImpl& context, Vec& out) const {
    const vector<Vec3>& pos = *platformData(context).positions;
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            out[3 * b + k] = pos[beadParticle[b]][k];
}

void ReferenceIntegrateRPYStepKernel::writePositions(ContextImpl& context, const Vec& in, bool shift) const {
    vector<Vec3>& pos = *platformData(context).positions;
    double com[3] = {0.0, 0.0, 0.0};
    if (shift) {
        // As knotmm.simulation: the force field sees the chain about its centre of mass, which
        // keeps single-precision platforms precise however far the chain has fallen.
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

void ReferenceIntegrateRPYStepKernel::velocity(ContextImpl& context, const Vec& yy, Vec& v) {
    writePositions(context, yy, true);
    context.calcForcesAndEnergy(true, false, context.getIntegrator().getIntegrationForceGroups());
    const vector<Vec3>& force = *platformData(context).forces;
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++) {
            xs[k * n + b] = yy[3 * b + k];
            fs[k * n + b] = force[beadParticle[b]][k];
        }
    mobility.velocities(n, xs.data(), fs.data(), vs.data());
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            v[3 * b + k] = vs[k * n + b];
    nEvaluations++;
}

void ReferenceIntegrateRPYStepKernel::computeGroupEnergies(ContextImpl& context, const vector<int>& groups,
                                                           vector<double>& energies) {
    // The positions the steps evaluate forces at (writePositions with the shift, bit for bit),
    // one energy-only evaluation per group, then the Context exactly as it was: positions,
    // virtual sites, force buffer and last force groups. The kernel's own state (cached
    // velocity, step size, noise stream, counters) is not touched.
    ReferencePlatform::PlatformData& data = platformData(context);
    const vector<Vec3> savedPositions = *data.positions;
    const vector<Vec3> savedForces = *data.forces;
    const int savedGroups = context.getLastForceGroups();
    Vec at(3 * n);
    readPositions(context, at);
    energies.assign(groups.size(), 0.0);
    try {
        writePositions(context, at, true);
        for (size_t i = 0; i < groups.size(); i++)
            energies[i] = context.calcForcesAndEnergy(false, true, 1 << groups[i]);
    }
    catch (...) {
        *data.positions = savedPositions;
        *data.forces = savedForces;
        context.getLastForceGroups() = savedGroups;
        throw;
    }
    *data.positions = savedPositions;
    *data.forces = savedForces;
    context.getLastForceGroups() = savedGroups;
}

double ReferenceIntegrateRPYStepKernel::errorNorm(const Vec& e, double tolerance) const {
    // largest per-bead displacement error over the tolerance; inf if anything is not finite
    double worst = 0.0;
    bool finite = true;
    for (int b = 0; b < n; b++) {
        const double s = e[3 * b] * e[3 * b] + e[3 * b + 1] * e[3 * b + 1] + e[3 * b + 2] * e[3 * b + 2];
        finite = finite && std::isfinite(s);
        worst = std::max(worst, s);
    }
    const double norm = std::sqrt(worst);
    return finite && std::isfinite(norm) ? norm / tolerance : std::numeric_limits<double>::infinity();
}

void ReferenceIntegrateRPYStepKernel::noiseSample(const Vec& yy, double scale, Vec& out) {
    if (scale == 0.0) {
        std::fill(out.begin(), out.end(), 0.0);
        return;
    }
    // out = scale B xi with B B^T = mu: 3n normals (bead-major) whichever the method
    for (int b = 0; b < n; b++)
        for (int k = 0; k < 3; k++)
            xs[k * n + b] = yy[3 * b + k];
    if (lanczos) {
        // B xi = mu^(1/2) xi by Lanczos, matrix-free (the pair loop of the velocities)
        for (int i = 0; i < 3 * n; i++)
            xi[i] = noise.normal();
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                zs[k * n + b] = xi[3 * b + k];
        lanczosSqrt.compute(mobility, n, xs.data(), zs.data(), lanczosTolerance, vs.data());
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                out[3 * b + k] = scale * vs[k * n + b];
        return;
    }
    // exact: dense Cholesky of the 3n x 3n mobility
    mobility.lowerMatrix(n, xs.data(), mat);
    const int dim = 3 * n;
    if (!choleskyLower(mat, dim))
        throw OpenMMException("RPYIntegrator: the RPY mobility is not positive definite at these "
                              "positions (two beads at the same point?)");
    for (int i = 0; i < dim; i++)
        xi[i] = noise.normal();
    lowerTimes(mat, dim, xi.data(), scale, out.data());
}

// ---------------------------------------------------------------------------------------------
// one accepted step

void ReferenceIntegrateRPYStepKernel::keepK1(ContextImpl& context, const Vec& at) {
    haveK1 = true;
    k1Positions = at;
    k1Parameters = context.getParameters();
}

double ReferenceIntegrateRPYStepKernel::execute(ContextImpl& context, RPYIntegrator& integrator, double targetTime) {
    // settings that may change between steps
    kT = integrator.getThermalEnergy();
    lanczos = integrator.getNoiseMethod() == "lanczos";
    lanczosTolerance = integrator.getLanczosTolerance();
    if (integrator.getNumThreads() != numThreads) {
        numThreads = integrator.getNumThreads();
        mobility = RPYMobility(integrator.getBeadDiameter(), integrator.getMobility(), numThreads);
    }
    readPositions(context, y);
    // The cached velocity is valid while positions and parameters are exactly those it was
    // computed at. (Checking them here, rather than trusting stateChanged(), keeps it across
    // Context.loadCheckpoint, which restores both and then reports them as changed.)
    if (haveK1 && (y != k1Positions || context.getParameters() != k1Parameters))
        invalidateCache();
    if (haveKick && y != kickPositions)
        haveKick = false;  // moved from outside: as knotmm's LeimkuhlerMatthews.reset()
    const double t0 = context.getTime();
    const double maxDt = std::isfinite(targetTime) ? targetTime - t0 : std::numeric_limits<double>::infinity();
    double h;
    try {
        if (method == RK23)
            h = stepRK23(context, integrator, maxDt);
        else if (method == RKC2)
            h = stepRKC2(context, integrator, maxDt);
        else
            h = stepFixed(context, std::min(integrator.getStepSize(), maxDt));
        for (int i = 0; i < 3 * n; i++)
            if (!std::isfinite(y1[i]))
                throw OpenMMException("RPYIntegrator (" + integrator.getMethod() + "): positions became non-finite at t = " +
                                      fmt(t0 + h) + " ps (bead " + std::to_string(i / 3) +
                                      "); the last good state is kept. Lower the step size or the error tolerance");
    }
    catch (...) {
        writePositions(context, y, false);
        haveK1 = false;
        haveKick = false;
        throw;
    }
    writePositions(context, y1, false);
    if (haveKick)
        kickPositions = y1;
    double t1 = t0 + h;
    if (std::isfinite(targetTime) && std::fabs(targetTime - t1) <= 1e-9 * std::max(1.0, std::fabs(targetTime)))
        t1 = targetTime;  // land exactly (knotmm.simulation's rule)
    context.setTime(t1);
    context.setStepCount(context.getStepCount() + 1);
    nAccepted++;
    return h;
}

double ReferenceIntegrateRPYStepKernel::stepFixed(ContextImpl& context, double h) {
    const int m = 3 * n;
    switch (method) {
    case EULER:
    case EULER_MARUYAMA:
        // y1 = y + h v(y) + sqrt(2 kT h) B xi
        noiseSample(y, std::sqrt(2.0 * kT * h), w);
        velocity(context, y, k1);
        for (int i = 0; i < m; i++)
            y1[i] = y[i] + h * k1[i] + w[i];
        break;
    case HEUN:
    case ITO_HEUN:
        // y* = y + h v(y) + W;  y1 = y + h/2 (v(y) + v(y*)) + W
        noiseSample(y, std::sqrt(2.0 * kT * h), w);
        velocity(context, y, k1);
        for (int i = 0; i < m; i++)
            ytmp[i] = y[i] + h * k1[i] + w[i];
        velocity(context, ytmp, k2);
        for (int i = 0; i < m; i++)
            y1[i] = y[i] + (0.5 * h) * (k1[i] + k2[i]) + w[i];
        break;
    case LEIMKUHLER_MATTHEWS: {
        // p = y + h v(y) + k;  k <- sqrt(kT h / 2) B(p) xi (held for the next step);  y1 = p + k
        // (knotmm.dynamics.brownian.LeimkuhlerMatthews; the first held kick is drawn at y)
        velocity(context, y, k1);
        if (kT == 0.0) {
            for (int i = 0; i < m; i++)
                y1[i] = y[i] + h * k1[i];
            break;
        }
        const double scale = std::sqrt(0.5 * kT * h);
        if (!haveKick || (int) kick.size() != m) {
            kick.assign(m, 0.0);
            noiseSample(y, scale, kick);
            haveKick = true;
        }
        for (int i = 0; i < m; i++)
            ytmp[i] = y[i] + h * k1[i] + kick[i];
        noiseSample(ytmp, scale, kick);
        for (int i = 0; i < m; i++)
            y1[i] = ytmp[i] + kick[i];
        break;
    }
    case MIDPOINT:
        // y1 = y + h v(y + h/2 v(y))
        velocity(context, y, k1);
        for (int i = 0; i < m; i++)
            ytmp[i] = y[i] + (0.5 * h) * k1[i];
        velocity(context, ytmp, k2);
        for (int i = 0; i < m; i++)
            y1[i] = y[i] + h * k2[i];
        break;
    default:
        throw OpenMMException("RPYIntegrator: internal error (fixed step of an adaptive method)");
    }
    return h;
}

double ReferenceIntegrateRPYStepKernel::stepRK23(ContextImpl& context, RPYIntegrator& integrator, double maxDt) {
    // Bogacki-Shampine 3(2), FSAL, PI step control: knotmm.integrators.RK23 line by line.
    const int m = 3 * n;
    const double tol = integrator.getErrorTolerance();
    if (!haveK1) {
        velocity(context, y, k1);
        keepK1(context, y);
    }
    while (true) {
        const double hTry = integrator.getStepSize();
        const double h = std::min(hTry, maxDt);
        for (int i = 0; i < m; i++)
            ytmp[i] = y[i] + 0.5 * h * k1[i];
        velocity(context, ytmp, k2);
        for (int i = 0; i < m; i++)
            ytmp[i] = y[i] + 0.75 * h * k2[i];
        velocity(context, ytmp, k3);
        for (int i = 0; i < m; i++)
            y1[i] = y[i] + h * (2.0 * k1[i] + 3.0 * k2[i] + 4.0 * k3[i]) / 9.0;
        velocity(context, y1, k4);
        for (int i = 0; i < m; i++)
            err[i] = h * (-5.0 / 72.0 * k1[i] + k2[i] / 12.0 + k3[i] / 9.0 - k4[i] / 8.0);
        const double e = errorNorm(err, tol);
        if (e <= 1.0) {
            double fac = 5.0;
            if (e != 0.0)
                fac = std::min(5.0, std::max(0.2, 0.9 * std::pow(e, -0.7 / 3.0) * std::pow(errOld, 0.4 / 3.0)));
            if (h >= hTry || fac < 1.0)  // a step clipped to land on targetTime keeps its size
                integrator.setStepSize(std::min(integrator.getMaximumStepSize(), h * fac));
            errOld = std::max(e, 1e-4);
            k1.swap(k4);
            keepK1(context, y1);
            return h;
        }
        nRejected++;
        const double fac = std::isfinite(e) ? std::max(0.2, 0.9 * std::pow(e, -1.0 / 3.0)) : 0.2;
        integrator.setStepSize(h * fac);
        if (h * fac < integrator.getMinimumStepSize())
            throw OpenMMException("RPYIntegrator (rk23): the step fell to " + fmt(h * fac) +
                                  " ps, below minimumStepSize, at t = " + fmt(context.getTime()) +
                                  " ps (error estimate " + fmt(e) + " x tolerance); the forces are too "
                                  "stiff here. The last good state is kept");
    }
}

const ReferenceIntegrateRPYStepKernel::Chebyshev& ReferenceIntegrateRPYStepKernel::chebyshev(int s) {
    // Damped s-stage RKC2 coefficients (knotmm.integrators._chebyshev_coefficients)
    auto found = chebyshevCache.find(s);
    if (found != chebyshevCache.end())
        return found->second;
    const double w0 = 1.0 + (2.0 / 13.0) / (s * s);
    vector<double> t(s + 1, 0.0), dt(s + 1, 0.0), ddt(s + 1, 0.0);
    t[0] = 1.0;
    t[1] = w0;
    dt[1] = 1.0;
    for (int j = 2; j <= s; j++) {
        t[j] = 2.0 * w0 * t[j - 1] - t[j - 2];
        dt[j] = 2.0 * t[j - 1] + 2.0 * w0 * dt[j - 1] - dt[j - 2];
        ddt[j] = 4.0 * dt[j - 1] + 2.0 * w0 * ddt[j - 1] - ddt[j - 2];
    }
    const double w1 = dt[s] / ddt[s];
    vector<double> b(s + 1, 0.0), a(s + 1, 0.0);
    for (int j = 2; j <= s; j++)
        b[j] = ddt[j] / (dt[j] * dt[j]);
    b[0] = b[1] = b[2];
    for (int j = 0; j <= s; j++)
        a[j] = 1.0 - b[j] * t[j];
    Chebyshev c;
    c.mu.assign(s + 1, 0.0);
    c.nu.assign(s + 1, 0.0);
    c.muT.assign(s + 1, 0.0);
    c.gammaT.assign(s + 1, 0.0);
    c.muT[1] = b[1] * w1;
    for (int j = 2; j <= s; j++) {
        c.mu[j] = 2.0 * w0 * b[j] / b[j - 1];
        c.nu[j] = -b[j] / b[j - 2];
        c.muT[j] = 2.0 * w1 * b[j] / b[j - 1];
        c.gammaT[j] = -a[j - 1] * c.muT[j];
    }
    return chebyshevCache[s] = c;
}

double ReferenceIntegrateRPYStepKernel::spectralRadius(ContextImpl& context, const Vec& yy, const Vec& f0) {
    // Nonlinear power iteration on finite differences of v (knotmm's RKC2.spectral_radius).
    const int m = 3 * n;
    const double size = 1e-3 * std::sqrt((double) m);
    Vec v(m);
    if (haveEig)
        v = eig;
    else if (!rkcStart.empty()) {
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                v[3 * b + k] = rkcStart[b][k];
    }
    else {
        NoiseStream start;  // fixed, independent of the noise stream
        start.seed(12345);
        for (int i = 0; i < m; i++)
            v[i] = start.normal();
    }
    double norm = 0.0;
    for (int i = 0; i < m; i++)
        norm += v[i] * v[i];
    norm = std::sqrt(norm);
    const double scale = size / std::max(norm, 1e-300);
    for (int i = 0; i < m; i++)
        v[i] *= scale;
    double sigma = 0.0;
    Vec probe(m), dv(m);
    for (int it = 0; it < 30; it++) {
        for (int i = 0; i < m; i++)
            probe[i] = yy[i] + v[i];
        velocity(context, probe, dv);
        double dn = 0.0;
        for (int i = 0; i < m; i++) {
            dv[i] -= f0[i];
            dn += dv[i] * dv[i];
        }
        dn = std::sqrt(dn);
        if (!std::isfinite(dn) || dn == 0.0)
            break;
        const double sigmaNew = dn / size;
        for (int i = 0; i < m; i++)
            v[i] = dv[i] * (size / dn);
        if (std::fabs(sigmaNew - sigma) <= 0.01 * sigmaNew) {
            sigma = sigmaNew;
            break;
        }
        sigma = sigmaNew;
    }
    eig = v;
    haveEig = true;
    return 1.2 * std::max(sigma, 1.0);
}

double ReferenceIntegrateRPYStepKernel::stepRKC2(ContextImpl& context, RPYIntegrator& integrator, double maxDt) {
    // Damped second-order Runge-Kutta-Chebyshev with error control: knotmm.integrators.RKC2.
    const int m = 3 * n;
    const int maxStages = 200, rhoInterval = 25;
    const double tol = integrator.getErrorTolerance();
    if (!haveK1) {
        velocity(context, y, k1);
        keepK1(context, y);
    }
    const Vec& f0 = k1;
    if (!haveRho || stepsSinceRho >= rhoInterval) {
        rho = spectralRadius(context, y, f0);
        haveRho = true;
        stepsSinceRho = 0;
    }
    if (stage.size() < 2)
        stage.assign(2, Vec(m));
    Vec& prev = stage[0];
    Vec& prev2 = stage[1];
    while (true) {
        const double hTry = integrator.getStepSize();
        double h = std::min(hTry, maxDt);
        int s = 1 + (int) std::sqrt(1.0 + 1.54 * h * rho);
        if (s > maxStages) {
            s = maxStages;
            h = std::min(h, 0.653 * (s * s - 1) / rho);
        }
        s = std::max(s, 2);
        const Chebyshev& c = chebyshev(s);
        prev2 = y;
        for (int i = 0; i < m; i++)
            prev[i] = y[i] + (c.muT[1] * h) * f0[i];
        for (int j = 2; j <= s; j++) {
            velocity(context, prev, k2);
            const double cy = 1.0 - c.mu[j] - c.nu[j], cf = c.muT[j] * h, cg = c.gammaT[j] * h;
            for (int i = 0; i < m; i++)
                ytmp[i] = cy * y[i] + c.mu[j] * prev[i] + c.nu[j] * prev2[i] + cf * k2[i] + cg * f0[i];
            prev2.swap(prev);
            prev.swap(ytmp);
        }
        y1 = prev;
        velocity(context, y1, k4);
        for (int i = 0; i < m; i++)
            err[i] = 0.8 * (y[i] - y1[i]) + (0.4 * h) * (f0[i] + k4[i]);
        const double e = errorNorm(err, tol);
        if (e <= 1.0) {
            // error-per-step PI rule of the RKC code
            double fac = 10.0;
            if (e > 0) {
                if (!haveRkcErrOld || !haveRkcHOld)
                    fac = std::min(fac, 0.8 * std::pow(e, -1.0 / 3.0));
                else
                    fac = std::min(fac, 0.8 * (h / rkcHOld) * std::pow(rkcErrOld, 1.0 / 3.0) / std::pow(e, 2.0 / 3.0));
            }
            fac = std::max(0.1, fac);
            if (!(h < hTry && fac >= 1.0)) {  // a step clipped to land keeps the wanted size
                rkcErrOld = std::max(e, 1e-10);
                haveRkcErrOld = true;
                rkcHOld = h;
                haveRkcHOld = true;
                integrator.setStepSize(std::min(integrator.getMaximumStepSize(), h * fac));
            }
            lastStages = s;
            k1.swap(k4);
            keepK1(context, y1);
            stepsSinceRho++;
            return h;
        }
        nRejected++;
        const double fac = std::isfinite(e) ? std::max(0.1, 0.8 * std::pow(e, -1.0 / 3.0)) : 0.1;
        integrator.setStepSize(h * fac);
        if (h * fac < integrator.getMinimumStepSize())
            throw OpenMMException("RPYIntegrator (rkc2): the step fell to " + fmt(h * fac) +
                                  " ps, below minimumStepSize, at t = " + fmt(context.getTime()) +
                                  " ps (error estimate " + fmt(e) + " x tolerance); the last good state is kept");
        rho = spectralRadius(context, y, f0);
        haveRho = true;
        stepsSinceRho = 0;
        haveRkcErrOld = false;
    }
}

// ---------------------------------------------------------------------------------------------
// checkpoints: everything that decides the next steps, so a restored run repeats bit for bit

void ReferenceIntegrateRPYStepKernel::createCheckpoint(std::ostream& stream) const {
    put(stream, KERNEL_CHECKPOINT_VERSION);
    put(stream, (int) method);
    put(stream, n);
    put(stream, nEvaluations);
    put(stream, nAccepted);
    put(stream, nRejected);
    put(stream, errOld);
    put(stream, haveK1);
    putVec(stream, haveK1 ? k1 : Vec());
    putVec(stream, haveK1 ? k1Positions : Vec());
    put(stream, (long long) k1Parameters.size());
    for (const auto& p : k1Parameters) {
        put(stream, (long long) p.first.size());
        stream.write(p.first.data(), p.first.size());
        put(stream, p.second);
    }
    put(stream, haveRho);
    put(stream, rho);
    put(stream, haveEig);
    putVec(stream, haveEig ? eig : Vec());
    put(stream, stepsSinceRho);
    put(stream, lastStages);
    put(stream, haveRkcErrOld);
    put(stream, rkcErrOld);
    put(stream, haveRkcHOld);
    put(stream, rkcHOld);
    noise.write(stream);
    put(stream, haveKick);
    putVec(stream, haveKick ? kick : Vec());
    putVec(stream, haveKick ? kickPositions : Vec());
}

void ReferenceIntegrateRPYStepKernel::loadCheckpoint(std::istream& stream) {
    int version = 0, savedMethod = 0, savedN = 0;
    get(stream, version);
    get(stream, savedMethod);
    get(stream, savedN);
    if ((version != KERNEL_CHECKPOINT_VERSION && version != 2) || savedMethod != (int) method || savedN != n)
        throw OpenMMException("RPYIntegrator: the checkpoint was written with another method, "
                              "bead count or plugin version");
    get(stream, nEvaluations);
    get(stream, nAccepted);
    get(stream, nRejected);
    get(stream, errOld);
    get(stream, haveK1);
    Vec tmp;
    getVec(stream, tmp);
    if (haveK1)
        k1 = tmp;
    getVec(stream, k1Positions);
    long long numParameters = 0;
    get(stream, numParameters);
    k1Parameters.clear();
    for (long long i = 0; i < numParameters; i++) {
        long long length = 0;
        get(stream, length);
        std::string name(length, ' ');
        stream.read(&name[0], length);
        get(stream, k1Parameters[name]);
    }
    get(stream, haveRho);
    get(stream, rho);
    get(stream, haveEig);
    getVec(stream, tmp);
    if (haveEig)
        eig = tmp;
    get(stream, stepsSinceRho);
    get(stream, lastStages);
    get(stream, haveRkcErrOld);
    get(stream, rkcErrOld);
    get(stream, haveRkcHOld);
    get(stream, rkcHOld);
    noise.read(stream);
    haveKick = false;
    if (version >= 3) {
        get(stream, haveKick);
        getVec(stream, kick);
        getVec(stream, kickPositions);
    }
    if (!stream)
        throw OpenMMException("RPYIntegrator: the checkpoint is truncated");
}
