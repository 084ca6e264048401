// The batch of copies on a device: its arrays and kernels, and its rounds (settle, evaluate).
// A copy's vectors and backend: CommonRPYArena.cpp.

#include "CommonRPYBatch.h"

#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/common/ContextSelector.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <sstream>

using namespace OpenMM;
using namespace KnotMM;
using std::string;
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
    checks.initialize<double>(cc, 3 * count, "rpyBatchChecks");
    table.initialize<double>(cc, 16 * (size_t) count, "rpyBatchTable");
    hostCentres.assign(4 * count, 0.0);
    hostChecks.assign(3 * count, 0.0);
    noiseScale.assign(count, 0.0);
    pending.resize(count);
    arena.reset(new CopyArena(cc, 3 * n, count));
    createCopies(integrator);  // the first copy's backend compiles the program (createKernels)
    for (int k = 0; k < 3; k++) {
        scratch.emplace_back(new CommonVector());
        scratch.back()->a.initialize<double>(cc, 3 * n, "rpyBatchScratch");
    }
}

std::unique_ptr<RPYBackend> CommonRPYBatch::makeBackend(int copy, const RPYIntegrator& settings) {
    const CommonRPYBackend* prototype = copy == 0 ? nullptr : &backendOf(0);
    std::unique_ptr<ArenaBackend> made(new ArenaBackend(*this, copy, cc, n, settings, prototype));
    if (copy == 0)  // before any vector is made: the arena grows with moveNumbers
        createKernels(*made);
    return std::unique_ptr<RPYBackend>(std::move(made));
}

void CommonRPYBatch::createKernels(const CommonRPYBackend& first) {
    ComputeProgram program = first.program;
    const bool mixed = cc.getUseMixedPrecision();
    ComputeKernel& move = arena->move;  // the arena's (CopyArena::moveNumbers)
    move = program->createKernel("moveNumbers");
    move->addArg(all);  // from, at, to, at, count: set per call
    move->addArg(0);
    move->addArg(all);
    move->addArg(0);
    move->addArg(0);
    gatherKernel = program->createKernel("gatherCopies");
    writeKernel = program->createKernel("writeCopies");
    readPositionsKernel = program->createKernel("readPositions");
    readForcesKernel = program->createKernel("readForces");
    mobilityKernel = program->createKernel("mobilityCopies");
    checkKernel = program->createKernel("checkCopies");
    normalsKernel = program->createKernel("normalsCopies");
    collectKernel = program->createKernel("collectVectors");
    spreadKernel = program->createKernel("spreadVectors");
    normalsKernel->addArg(all);  // arena, table: set per call
    normalsKernel->addArg(table);
    normalsKernel->addArg(0);
    normalsKernel->addArg(0);
    for (ComputeKernel* k : {&collectKernel, &spreadKernel}) {  // all: the arena or bulk, set per call
        (*k)->addArg(all);
        (*k)->addArg(table);
        (*k)->addArg(0);
        (*k)->addArg(0);
        (*k)->addArg(all);
    }
    for (ComputeKernel* k : {&gatherKernel, &checkKernel})
        if ((*k)->getMaxBlockSize() < first.reduceSize)
            throw OpenMMException("RPYIntegrator: the device runs kernel " + (*k)->getName() +
                                  " in work groups of at most " + std::to_string((*k)->getMaxBlockSize()) +
                                  " items, fewer than it needs");
    if (mobilityKernel->getMaxBlockSize() < first.tileSize)
        throw OpenMMException("RPYIntegrator: the device runs kernel mobilityCopies in work groups of at most " +
                              std::to_string(mobilityKernel->getMaxBlockSize()) + " items, fewer than it needs");
    // the arena and the table: set per call (either may grow)
    gatherKernel->addArg(all);
    gatherKernel->addArg(table);
    gatherKernel->addArg(0);
    gatherKernel->addArg(0);
    gatherKernel->addArg(all);
    gatherKernel->addArg(centres);
    writeKernel->addArg(cc.getPosq());
    if (mixed)
        writeKernel->addArg(cc.getPosqCorrection());
    writeKernel->addArg(cc.getAtomIndexArray());
    writeKernel->addArg(particleBead);
    writeKernel->addArg(all);
    writeKernel->addArg(centres);
    writeKernel->addArg(0.0);  // spacing: set per call
    writeKernel->addArg(side);
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
    mobilityKernel->addArg(all);  // arena
    mobilityKernel->addArg(allForces);
    mobilityKernel->addArg(table);
    mobilityKernel->addArg(0);
    mobilityKernel->addArg(0);
    mobilityKernel->addArg(first.diameter);
    mobilityKernel->addArg(first.mu0);
    checkKernel->addArg(all);  // arena
    checkKernel->addArg(table);
    checkKernel->addArg(0);
    checkKernel->addArg(0);
    checkKernel->addArg(checks);
}

ComputeKernel& CommonRPYBatch::combineKernel(const string& pattern) {
    auto found = combineKernels.find(pattern);
    if (found != combineKernels.end())
        return found->second;
    // For listed copy c, its entry e = table + base + c (1 + 2 count): arena[e[0] + i] = t_0 +
    // t_1 + ..., added left to right, t_k = e[2 + 2k] arena[e[1 + 2k] + i] ('m') or
    // arena[e[1 + 2k] + i] / e[2 + 2k] ('d'), as CommonRPYBackend::combine; "z": 0.
    const int count = pattern == "z" ? 0 : (int) pattern.size();
    std::stringstream src;
    src << "KERNEL void combineCopies(GLOBAL double* arena, GLOBAL const double* RESTRICT table, int base, "
           "int copies) {\n"
           "    for (int g = GLOBAL_ID; g < copies*SIZE; g += GLOBAL_SIZE) {\n"
           "        const int c = g/SIZE, i = g-c*SIZE;\n"
           "        GLOBAL const double* e = table+base+c*"
        << 1 + 2 * count << ";\n";
    if (count == 0)
        src << "        const double acc = 0.0;\n";
    for (int k = 0; k < count; k++) {
        const string v = "arena[(int) e[" + std::to_string(1 + 2 * k) + "]+i]";
        const string c = "e[" + std::to_string(2 + 2 * k) + "]";
        const string term = pattern[k] == 'd' ? v + "/" + c : c + "*" + v;
        src << (k == 0 ? "        double acc = " : "        acc = acc + ") << term << ";\n";
    }
    src << "        arena[(int) e[0]+i] = acc;\n    }\n}\n";
    std::map<string, string> defines = {{"SIZE", cc.intToString(3 * n)}};
    ComputeProgram program = cc.compileProgram(src.str(), defines);
    combinePrograms[pattern] = program;
    ComputeKernel kernel = program->createKernel("combineCopies");
    kernel->addArg(all);  // arena, table: set per call
    kernel->addArg(table);
    kernel->addArg(0);
    kernel->addArg(0);
    return combineKernels[pattern] = kernel;
}

void CommonRPYBatch::uploadTable() {
    if (hostTable.empty())
        return;
    if (table.getSize() < hostTable.size())
        table.resize(std::max(hostTable.size(), 2 * table.getSize()));
    table.uploadSubArray(hostTable.data(), 0, (int) hostTable.size());
}

void CommonRPYBatch::launchPending() {
    // The i-th operations of all copies, grouped by pattern, in one launch each; a copy's
    // operations in its order (launch i+1 after launch i on the one queue). The table (this
    // round's, started by the caller) gets each launch's entries; uploaded once, then launched.
    launches.clear();
    size_t longest = 0;
    for (const auto& ops : pending)
        longest = std::max(longest, ops.size());
    for (size_t i = 0; i < longest; i++) {
        done.assign(pending.size(), 0);
        for (size_t first = 0; first < pending.size(); first++) {
            if (done[first] || pending[first].size() <= i)
                continue;
            const string& pattern = pending[first][i].pattern;
            Launch launch{pattern, tableAt(), 0};
            for (size_t k = first; k < pending.size(); k++) {
                if (done[k] || pending[k].size() <= i || pending[k][i].pattern != pattern)
                    continue;
                done[k] = 1;
                const DeferredOp& op = pending[k][i];
                hostTable.push_back(op.out);
                if (pattern == "n")
                    hostTable.insert(hostTable.end(), op.c, op.c + 4);
                const int count = pattern == "z" || pattern == "n" ? 0 : (int) pattern.size();
                for (int t = 0; t < count; t++) {
                    hostTable.push_back(op.in[t]);
                    hostTable.push_back(op.c[t]);
                }
                launch.copies++;
            }
            launches.push_back(launch);
        }
    }
    for (auto& ops : pending)
        ops.clear();
    uploadTable();
    for (const Launch& launch : launches) {
        if (launch.pattern == "n") {
            normalsKernel->setArg(0, *arena->numbers);
            normalsKernel->setArg(1, table);
            normalsKernel->setArg(2, launch.base);
            normalsKernel->setArg(3, launch.copies);
            normalsKernel->execute(launch.copies * ((3 * n + 3) / 4));
            continue;
        }
        ComputeKernel& kernel = combineKernel(launch.pattern);
        kernel->setArg(0, *arena->numbers);
        kernel->setArg(1, table);
        kernel->setArg(2, launch.base);
        kernel->setArg(3, launch.copies);
        kernel->execute(launch.copies * 3 * n);
    }
}

void CommonRPYBatch::settle() {
    // One round: the recorded operations, the noise the copies wait for (makeNoise), then
    // their checks, with one upload of the table and one download of the checks.
    hostTable.clear();
    checking.clear();
    for (int j = 0; j < numCopies(); j++)
        if (copyAt(j).state == State::WaitingForCheck)
            checking.push_back(j);
    try {
        launchPending();
        makeNoise();
        if (checking.empty())
            return;
        hostTable.clear();
        for (int j : checking) {
            const Copy& c = copyAt(j);
            hostTable.push_back(c.request2 != nullptr ? arenaOffset(*c.request2) : -1);
            hostTable.push_back(arenaOffset(*c.request));
        }
        uploadTable();
        const int reduceSize = backendOf(0).reduceSize;
        checkKernel->setArg(0, *arena->numbers);
        checkKernel->setArg(1, table);
        checkKernel->setArg(2, 0);
        checkKernel->setArg(3, (int) checking.size());
        checkKernel->execute(std::min((int) checking.size(), cc.getNumThreadBlocks()) * reduceSize, reduceSize);
        checks.download(hostChecks.data());  // the one download of the round's checks
        for (size_t i = 0; i < checking.size(); i++)
            copyAt(checking[i]).check = backendOf(0).tryCheckOf(&hostChecks[3 * i]);
    }
    catch (...) {
        for (int j = 0; j < numCopies(); j++)
            if (copyAt(j).state != State::Done && copyAt(j).state != State::Idle)
                copyAt(j).jobError = std::current_exception();
        return;
    }
}

void CommonRPYBatch::makeNoise() {
    noisy.clear();
    for (int j = 0; j < numCopies(); j++)
        if (copyAt(j).state == State::WaitingForNoise)
            noisy.push_back(j);
    if (noisy.empty())
        return;
    const int dim = 3 * n;
    // entries: each noisy copy's y to factor at (where pending), then its z
    hostTable.clear();
    factorEntry.clear();
    zEntry.clear();
    for (int j : noisy) {
        ArenaBackend& b = backendOf(j);
        factorEntry.push_back(b.factorPending ? tableAt() : -1);
        if (b.factorPending)
            hostTable.push_back(arenaOffset(*b.factorPoint));
        zEntry.push_back(tableAt());
        hostTable.push_back(arenaOffset(*copyAt(j).request));
    }
    const int entries = tableAt();
    if (!bulk.isInitialized() || bulk.getSize() < (size_t) entries * dim) {
        const size_t size = (size_t) std::max(entries, 2 * numCopies()) * dim;
        if (bulk.isInitialized())
            bulk.resize(size);
        else
            bulk.initialize<double>(cc, size, "rpyBatchNoise");
    }
    uploadTable();
    collectKernel->setArg(0, *arena->numbers);
    collectKernel->setArg(1, table);
    collectKernel->setArg(3, entries);
    collectKernel->setArg(4, bulk);
    collectKernel->execute(entries * dim);
    bulk.download(hostBulk);  // the round's one download of noise requests
    // on the host, as CommonRPYBackend::factorNoise and applyNoise: each copy's own factor,
    // the copies shared out over the integrator's threads
    hostNoise.resize(noisy.size() * dim);
    noiseFailed.assign(noisy.size(), 0);
    noiseJobs.resize(noisy.size());
    for (size_t i = 0; i < noisy.size(); i++)
        noiseJobs[i] = (int) i;
    shareOut(noiseJobs, [&](int i) {
        ArenaBackend& b = backendOf(noisy[i]);
        try {
            if (factorEntry[i] >= 0) {
                b.factorPending = false;
                b.factorAt(&hostBulk[(size_t) factorEntry[i] * dim]);
            }
            b.cholesky.times(&hostBulk[(size_t) zEntry[i] * dim], noiseScale[noisy[i]], &hostNoise[(size_t) i * dim]);
        }
        catch (...) {
            copyAt(noisy[i]).jobError = std::current_exception();
            noiseFailed[i] = 1;
        }
    });
    hostTable.clear();  // the replies of the copies that got one, packed in order
    for (size_t i = 0; i < noisy.size(); i++) {
        if (noiseFailed[i])
            continue;
        if (tableAt() != (int) i)
            std::copy_n(&hostNoise[i * dim], dim, &hostNoise[(size_t) tableAt() * dim]);
        hostTable.push_back(arenaOffset(*copyAt(noisy[i]).reply));
    }
    const int replies = tableAt();
    if (replies == 0)
        return;
    uploadTable();
    bulk.uploadSubArray(hostNoise.data(), 0, replies * dim);
    spreadKernel->setArg(0, bulk);
    spreadKernel->setArg(1, table);
    spreadKernel->setArg(3, replies);
    spreadKernel->setArg(4, *arena->numbers);
    spreadKernel->execute(replies * dim);
}

void CommonRPYBatch::readContextPositions(ContextImpl&, int copy, StateVector& positions) {
    if (!readAll) {  // once for all copies never given positions
        readPositionsKernel->execute(cc.getNumAtoms());
        readAll = true;
    }
    settleCopy(copy);  // the vector's zeros first
    arena->moveNumbers(all, 3 * n * copy, *arena->numbers, arenaOffset(positions), 3 * n);
}

void CommonRPYBatch::evaluate(ContextImpl& context) {
    const int count = numCopies();
    const int reduceSize = backendOf(0).reduceSize, tileSize = backendOf(0).tileSize;
    hostTable.clear();
    waiting.clear();
    for (int j = 0; j < count; j++) {
        const Copy& c = copyAt(j);
        hostTable.push_back(arenaOffset(c.state == State::WaitingForVelocity ? *c.request : *c.positions));
        if (c.state == State::WaitingForVelocity)
            waiting.push_back(j);
    }
    const int mobilityAt = tableAt();
    for (int j : waiting) {
        const Copy& c = copyAt(j);
        hostTable.push_back(arenaOffset(*c.request));
        hostTable.push_back(j);
        hostTable.push_back(arenaOffset(*c.reply));
    }
    try {
        uploadTable();
        gatherKernel->setArg(0, *arena->numbers);
        gatherKernel->setArg(1, table);
        gatherKernel->setArg(2, 0);
        gatherKernel->setArg(3, count);
        gatherKernel->execute(std::min(count, cc.getNumThreadBlocks()) * reduceSize, reduceSize);
    }
    catch (const std::exception& error) {
        forceError = error.what();
        return;
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
    try {
        readForcesKernel->execute(cc.getNumAtoms());
        // the mobility depends on differences only: each copy's y itself
        const int tiles = (n + tileSize - 1) / tileSize;
        const int units = (int) waiting.size() * tiles;
        mobilityKernel->setArg(0, *arena->numbers);
        mobilityKernel->setArg(2, table);
        mobilityKernel->setArg(3, mobilityAt);
        mobilityKernel->setArg(4, (int) waiting.size());
        mobilityKernel->execute(std::max(1, std::min(units, cc.getNumThreadBlocks())) * tileSize, tileSize);
    }
    catch (const std::exception& error) {
        forceError = error.what();
    }
}

bool CommonRPYBatch::stepTo(ContextImpl& context, RPYIntegrator& integrator, const vector<double>& targets,
                            double maxSeconds) {
    ContextSelector selector(cc);
    readAll = false;
    return CopyBatch::stepTo(context, integrator, targets, maxSeconds);
}

// --- the kernel's copies -------------------------------------------------------------------------

std::unique_ptr<RPYCopies> CommonIntegrateRPYStepKernel::createCopies(const System& system,
                                                                      const RPYIntegrator& integrator) {
    ContextSelector selector(cc);
    return std::unique_ptr<RPYCopies>(new CommonRPYBatch(cc, system, integrator));
}
