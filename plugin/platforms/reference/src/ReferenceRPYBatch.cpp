#include "ReferenceRPYBatch.h"

#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"
#include "openmm/reference/ReferencePlatform.h"

#include <algorithm>
#include <cmath>

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

// --- a copy's backend ----------------------------------------------------------------------------

CopyBackend::CopyBackend(ReferenceRPYBatch& batch, int copy, int numBeads, const RPYIntegrator& integrator, int threads,
                         bool singleForces)
    : BatchedBackend<ReferenceRPYBackend>(batch, copy, numBeads, integrator, singleForces), threads(threads) {}

void CopyBackend::factorNoise(const StateVector& y) {
    if (lanczosNoise() || threads < 2) {
        // matrix-free, or no threads to share it out: factorised here, where the copy's
        // next steps use the factor while it is still in the cache
        ReferenceRPYBackend::factorNoise(y);
        return;
    }
    batch.waitForFactor(index, y);
}

// --- the batch -----------------------------------------------------------------------------------

ReferenceRPYBatch::ReferenceRPYBatch(const System& system, const RPYIntegrator& integrator, bool singleForces)
    : CopyBatch(system, integrator), singleForces(singleForces) {
    forces.assign(integrator.getNumCopies(), vector<Vec3>(n));
    createCopies(integrator);
}

std::unique_ptr<RPYBackend> ReferenceRPYBatch::makeBackend(int copy, const RPYIntegrator& settings) {
    // the copy's settings say one thread; the batch's count decides where factors are made
    return std::unique_ptr<RPYBackend>(new CopyBackend(*this, copy, n, settings, threads, singleForces));
}

void ReferenceRPYBatch::readContextPositions(ContextImpl& context, int copy, StateVector& positions) {
    const vector<Vec3>& from = *platformData(context).positions;
    vector<double>& y = data(positions);
    for (int b = 0; b < n; b++)
        for (int i = 0; i < 3; i++)
            y[3 * b + i] = from[beadParticle[copy * n + b]][i];
}

void ReferenceRPYBatch::runJobs() {
    jobs.clear();  // (a member: nothing is allocated once every copy has waited at once)
    for (int k = 0; k < numCopies(); k++) {
        const Copy& c = copyAt(k);
        if ((c.state == State::WaitingForVelocity && forceError.empty()) || c.state == State::WaitingForFactor)
            jobs.push_back(k);
    }
    auto work = [&](int k) {
        Copy& c = copyAt(k);
        CopyBackend& backend = static_cast<CopyBackend&>(*c.backend);
        try {
            if (c.state == State::WaitingForVelocity)
                backend.velocityJob(data(*c.request), forces[k], data(*c.reply));
            else
                backend.factorJob(*c.request);
        }
        catch (...) {
            c.jobError = std::current_exception();
        }
    };
    shareOut(jobs, work);
}

void ReferenceRPYBatch::evaluate(ContextImpl& context) {
    // Each copy at its own grid point: its beads shifted to their centre of mass (as one system
    // alone is evaluated), then moved to the point.
    const int count = numCopies();
    at.resize(count);
    centre.resize(count);
    double reach = 0.0;
    for (int j = 0; j < count; j++) {
        const Copy& c = copyAt(j);
        at[j] = c.state == State::WaitingForVelocity ? &data(*c.request) : &data(*c.positions);
        const vector<double>& y = *at[j];
        double com[3] = {0.0, 0.0, 0.0};
        for (int b = 0; b < n; b++)
            for (int k = 0; k < 3; k++)
                com[k] += y[3 * b + k];
        for (int k = 0; k < 3; k++)
            com[k] /= n;
        centre[j] = Vec3(com[0], com[1], com[2]);
        for (int b = 0; b < n; b++) {
            const double dx = y[3 * b] - com[0], dy = y[3 * b + 1] - com[1], dz = y[3 * b + 2] - com[2];
            reach = std::max(reach, std::sqrt(dx * dx + dy * dy + dz * dz));
        }
    }
    placeCopies(reach);
    vector<Vec3>& pos = *platformData(context).positions;
    for (int j = 0; j < count; j++) {
        double off[3];
        gridOffset(j, off);
        const vector<double>& y = *at[j];
        for (int b = 0; b < n; b++)
            pos[beadParticle[j * n + b]] = Vec3((y[3 * b] - centre[j][0]) + off[0], (y[3 * b + 1] - centre[j][1]) + off[1],
                                                (y[3 * b + 2] - centre[j][2]) + off[2]);
    }
    if (!calcForces(context, [&]() { context.computeVirtualSites(); }))
        return;
    const vector<Vec3>& force = *platformData(context).forces;
    for (int j = 0; j < count; j++) {
        if (copyAt(j).state != State::WaitingForVelocity)
            continue;
        for (int b = 0; b < n; b++)
            forces[j][b] = force[beadParticle[j * n + b]];
    }
}
