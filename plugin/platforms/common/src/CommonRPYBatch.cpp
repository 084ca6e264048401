#include "CommonRPYBatch.h"

#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/common/ContextSelector.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

CommonRPYBatch::CommonRPYBatch(ComputeContext& cc, const System& system, const RPYIntegrator& integrator)
    : CopyBatch(system, integrator), cc(cc) {
    const int count = integrator.getNumCopies();
    while (side * side * side < count)
        side++;
    vector<int> beadOf(system.getNumParticles(), -1);
    for (int g = 0; g < (int) beadParticle.size(); g++)
        beadOf[beadParticle[g]] = g;
    particleBead.initialize<int>(cc, beadOf.size(), "rpyBatchParticleBead");
    particleBead.upload(beadOf);
    all.initialize<double>(cc, 3 * (size_t) n * count, "rpyBatchPositions");
    allForces.initialize<double>(cc, 3 * (size_t) n * count, "rpyBatchForces");
    centres.initialize<double>(cc, 4 * count, "rpyBatchCentres");
    hostCentres.assign(4 * count, 0.0);
    createCopies(integrator);
    createKernels();
}

std::unique_ptr<RPYBackend> CommonRPYBatch::makeBackend(int copy, const RPYIntegrator& settings) {
    const CommonRPYBackend* prototype = copy == 0 ? nullptr : &backendOf(0);
    return std::unique_ptr<RPYBackend>(new BatchedBackend<CommonRPYBackend>(*this, copy, cc, n, settings, prototype));
}

void CommonRPYBatch::createKernels() {
    ComputeProgram& program = backendOf(0).program;
    const bool mixed = cc.getUseMixedPrecision();
    gatherKernel = program->createKernel("gatherCopy");
    writeKernel = program->createKernel("writeCopies");
    scatterKernel = program->createKernel("scatterCopy");
    readPositionsKernel = program->createKernel("readPositions");
    readForcesKernel = program->createKernel("readForces");
    if (gatherKernel->getMaxBlockSize() < backendOf(0).reduceSize)
        throw OpenMMException("RPYIntegrator: the device runs kernel gatherCopy in work groups of at most " +
                              std::to_string(gatherKernel->getMaxBlockSize()) + " items, fewer than it needs");
    gatherKernel->addArg(all);  // y: set per call
    gatherKernel->addArg(all);
    gatherKernel->addArg(centres);
    gatherKernel->addArg(0);
    writeKernel->addArg(cc.getPosq());
    if (mixed)
        writeKernel->addArg(cc.getPosqCorrection());
    writeKernel->addArg(cc.getAtomIndexArray());
    writeKernel->addArg(particleBead);
    writeKernel->addArg(all);
    writeKernel->addArg(centres);
    writeKernel->addArg(0.0);  // spacing: set per call
    writeKernel->addArg(side);
    scatterKernel->addArg(allForces);
    scatterKernel->addArg(allForces);  // out, copy: set per call
    scatterKernel->addArg(0);
    readPositionsKernel->addArg(cc.getPosq());
    if (mixed)
        readPositionsKernel->addArg(cc.getPosqCorrection());
    readPositionsKernel->addArg(cc.getAtomIndexArray());
    readPositionsKernel->addArg(particleBead);
    readPositionsKernel->addArg(all);
    readForcesKernel->addArg(cc.getLongForceBuffer());
    readForcesKernel->addArg(cc.getAtomIndexArray());
    readForcesKernel->addArg(particleBead);
    readForcesKernel->addArg(allForces);
}

void CommonRPYBatch::readContextPositions(ContextImpl&, int copy, StateVector& positions) {
    if (!readAll) {  // once for all copies never given positions
        readPositionsKernel->execute(cc.getNumAtoms());
        readAll = true;
    }
    scatterKernel->setArg(0, all);
    scatterKernel->setArg(1, data(positions));
    scatterKernel->setArg(2, copy);
    scatterKernel->execute(3 * n);
}

void CommonRPYBatch::evaluate(ContextImpl& context) {
    const int count = numCopies();
    const int reduceSize = backendOf(0).reduceSize;
    for (int j = 0; j < count; j++) {
        const Copy& c = copyAt(j);
        gatherKernel->setArg(0, data(c.state == State::WaitingForVelocity ? *c.request : *c.positions));
        gatherKernel->setArg(3, j);
        gatherKernel->execute(reduceSize, reduceSize);
    }
    double reach = 0.0;
    if (apart) {  // the grid's spacing from the widest copy: the one download of an evaluation
        centres.download(hostCentres);
        for (int j = 0; j < count; j++)
            if (hostCentres[4 * j + 3] > reach)
                reach = hostCentres[4 * j + 3];
    }
    writeKernel->setArg(cc.getUseMixedPrecision() ? 6 : 5, placeCopies(reach));
    writeKernel->execute(cc.getNumAtoms());
    if (!calcForces(context, [&]() { cc.getIntegrationUtilities().computeVirtualSites(); }))
        return;
    readForcesKernel->execute(cc.getNumAtoms());
    for (int j = 0; j < count; j++) {
        Copy& c = copyAt(j);
        if (c.state != State::WaitingForVelocity)
            continue;
        CommonRPYBackend& backend = backendOf(j);
        try {
            scatterKernel->setArg(0, allForces);
            scatterKernel->setArg(1, backend.forces);
            scatterKernel->setArg(2, j);
            scatterKernel->execute(3 * n);
            // the mobility depends on differences only: the copy's y itself
            backend.mobilityTimes(data(*c.request), backend.forces, data(*c.reply));
        }
        catch (...) {
            c.jobError = std::current_exception();
        }
    }
}

bool CommonRPYBatch::stepTo(ContextImpl& context, RPYIntegrator& integrator, const vector<double>& targets,
                            double maxSeconds) {
    ContextSelector selector(cc);
    readAll = false;
    return CopyBatch::stepTo(context, integrator, targets, maxSeconds);
}

vector<double> CommonRPYBatch::getPositions(int copy) const {
    ContextSelector selector(cc);
    return CopyBatch::getPositions(copy);
}

void CommonRPYBatch::setPositions(int copy, const vector<double>& positions) {
    ContextSelector selector(cc);
    CopyBatch::setPositions(copy, positions);
}

void CommonRPYBatch::createCheckpoint(int copy, std::ostream& stream) const {
    ContextSelector selector(cc);
    CopyBatch::createCheckpoint(copy, stream);
}

void CommonRPYBatch::loadCheckpoint(int copy, std::istream& stream) {
    ContextSelector selector(cc);
    CopyBatch::loadCheckpoint(copy, stream);
}

// --- the kernel's copies -------------------------------------------------------------------------

std::unique_ptr<RPYCopies> CommonIntegrateRPYStepKernel::createCopies(const System& system,
                                                                      const RPYIntegrator& integrator) {
    ContextSelector selector(cc);
    return std::unique_ptr<RPYCopies>(new CommonRPYBatch(cc, system, integrator));
}
