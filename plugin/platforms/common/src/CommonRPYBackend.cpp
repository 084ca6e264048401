#include "CommonRPYBackend.h"

#include "CommonRPYKernelSources.h"
#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYStepFault.h"
#include "knotmm/stepper/NoiseStream.h"
#include "openmm/OpenMMException.h"
#include "openmm/System.h"
#include "openmm/common/ContextSelector.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

using namespace OpenMM;
using namespace KnotMM;
using std::string;
using std::vector;

using KnotMM::data;

CommonRPYBackend::CommonRPYBackend(ComputeContext& cc, const System& system, const RPYIntegrator& integrator)
    : cc(cc), diameter(integrator.getBeadDiameter()), mu0(integrator.getMobility()),
      hostMobility(diameter, mu0, 1) {
    vector<int> beadOf(system.getNumParticles(), -1);
    for (int i = 0; i < system.getNumParticles(); i++) {
        if (system.isVirtualSite(i))
            hasVirtualSites = true;
        else
            beadOf[i] = n++;
    }
    particleBead.initialize<int>(cc, beadOf.size(), "rpyParticleBead");
    particleBead.upload(beadOf);
    setUp(integrator, nullptr);
}

CommonRPYBackend::CommonRPYBackend(ComputeContext& cc, int numBeads, const RPYIntegrator& integrator,
                                   const CommonRPYBackend* prototype)
    : cc(cc), n(numBeads), diameter(integrator.getBeadDiameter()), mu0(integrator.getMobility()),
      hostMobility(diameter, mu0, 1) {
    setUp(integrator, prototype);
}

void CommonRPYBackend::setUp(const RPYIntegrator& integrator, const CommonRPYBackend* prototype) {
    if (!cc.getSupportsDoublePrecision())
        throw OpenMMException("RPYIntegrator: this device has no double precision, which the RPY integrator "
                              "needs (its state and sums are in double); use another device or the CPU platform");
    mixed = cc.getUseMixedPrecision();
    single = !mixed && !cc.getUseDoublePrecision();
    numAtoms = cc.getNumAtoms();
    tileSize = ComputeContext::TileSize;
    reduceSize = 128;
    while (reduceSize > 1 && reduceSize > cc.getMaxThreadBlockSize())
        reduceSize /= 2;
    com.initialize<double>(cc, 3, "rpyCentreOfMass");
    scalars.initialize<double>(cc, 3, "rpyScalars");
    counts.initialize<int>(cc, 1, "rpyCounts");
    for (ComputeArray* a : {&forces, &noiseAt, &lanczosV, &lanczosW, &energyPosition})
        a->initialize<double>(cc, 3 * n, "rpyVector");

    defines["NUM_BEADS"] = cc.intToString(n);
    defines["NUM_ATOMS"] = cc.intToString(numAtoms);
    defines["PADDED_NUM_ATOMS"] = cc.intToString(cc.getPaddedNumAtoms());
    defines["TILE"] = cc.intToString(tileSize);
    defines["REDUCE_SIZE"] = cc.intToString(reduceSize);
    if (single)
        defines["KNOTMM_SINGLE"] = "1";
    if (prototype != nullptr) {  // a copy of a batch: the first copy's programs
        program = prototype->program;
        combinePrograms = prototype->combinePrograms;
    }
    else {
        program = cc.compileProgram(CommonRPYKernelSources::rpy, defines);
        combinePrograms.reset(new std::map<string, ComputeProgram>());
    }
    readPositionsKernel = program->createKernel("readPositions");
    writePositionsKernel = program->createKernel("writePositions");
    centreOfMassKernel = program->createKernel("centreOfMass");
    readForcesKernel = program->createKernel("readForces");
    mobilityKernel = program->createKernel("mobilityTimes");
    sumSquaresKernel = program->createKernel("sumSquares");
    firstNonFiniteKernel = program->createKernel("firstNonFinite");
    countDifferentKernel = program->createKernel("countDifferent");
    checkTryKernel = program->createKernel("checkTry");
    lanczosDotsKernel = program->createKernel("lanczosDots");
    lanczosSubtractKernel = program->createKernel("lanczosSubtract");
    lanczosAlphaBetaKernel = program->createKernel("lanczosAlphaBeta");
    lanczosScaleKernel = program->createKernel("lanczosScale");
    lanczosCombineKernel = program->createKernel("lanczosCombine");
    counterNormalsKernel = program->createKernel("counterNormals");
    // the pair loop and the reductions run in work groups of exactly TILE and REDUCE_SIZE items
    for (ComputeKernel* k : {&mobilityKernel, &sumSquaresKernel, &firstNonFiniteKernel,
                             &countDifferentKernel, &centreOfMassKernel, &checkTryKernel, &lanczosDotsKernel,
                             &lanczosAlphaBetaKernel})
        if ((*k)->getMaxBlockSize() < (k == &mobilityKernel ? tileSize : reduceSize))
            throw OpenMMException("RPYIntegrator: the device runs kernel " + (*k)->getName() + " in work groups of at most " +
                                  std::to_string((*k)->getMaxBlockSize()) + " items, fewer than it needs");

    // Arguments that never change are set once; vectors are set at each call (setArg). A copy
    // of a batch reads and writes no Context itself (CommonRPYBatch does).
    if (particleBead.isInitialized())
        bindContext();
    mobilityKernel->addArg(noiseAt);  // x, f, v: set per call
    mobilityKernel->addArg(forces);
    mobilityKernel->addArg(lanczosW);
    mobilityKernel->addArg(diameter);
    mobilityKernel->addArg(mu0);
    sumSquaresKernel->addArg(forces);  // set per call
    sumSquaresKernel->addArg(scalars);
    firstNonFiniteKernel->addArg(forces);  // set per call
    firstNonFiniteKernel->addArg(counts);
    countDifferentKernel->addArg(forces);  // a, b: set per call
    countDifferentKernel->addArg(forces);
    countDifferentKernel->addArg(counts);
    // Lanczos (CommonRPYNoise.cpp): every argument set at each use
    for (ComputeKernel* k : {&lanczosDotsKernel, &lanczosSubtractKernel}) {
        for (int i = 0; i < 3; i++)
            (*k)->addArg(forces);
        (*k)->addArg(0);
        (*k)->addArg(0);
    }
    lanczosAlphaBetaKernel->addArg(forces);
    lanczosAlphaBetaKernel->addArg(forces);
    lanczosAlphaBetaKernel->addArg(0);
    lanczosAlphaBetaKernel->addArg(forces);
    lanczosScaleKernel->addArg(forces);
    lanczosScaleKernel->addArg(forces);
    lanczosScaleKernel->addArg(0);
    lanczosScaleKernel->addArg(1.0);
    lanczosScaleKernel->addArg(forces);
    lanczosCombineKernel->addArg(forces);
    lanczosCombineKernel->addArg(forces);
    lanczosCombineKernel->addArg(0);
    lanczosCombineKernel->addArg(forces);
    counterNormalsKernel->addArg(forces);  // out, key, draw: set per call
    counterNormalsKernel->addArg((unsigned long long) 0);
    counterNormalsKernel->addArg((unsigned long long) 0);
    checkTryKernel->addArg(forces);  // err, y1: set per call
    checkTryKernel->addArg(forces);
    checkTryKernel->addArg(scalars);
    applySettings(integrator);
}

void CommonRPYBackend::bindContext() {
    readPositionsKernel->addArg(cc.getPosq());
    if (mixed)
        readPositionsKernel->addArg(cc.getPosqCorrection());
    readPositionsKernel->addArg(cc.getAtomIndexArray());
    readPositionsKernel->addArg(particleBead);
    readPositionsKernel->addArg(forces);  // y, set per call
    writePositionsKernel->addArg(cc.getPosq());
    if (mixed)
        writePositionsKernel->addArg(cc.getPosqCorrection());
    writePositionsKernel->addArg(cc.getAtomIndexArray());
    writePositionsKernel->addArg(particleBead);
    writePositionsKernel->addArg(forces);  // y, set per call
    writePositionsKernel->addArg(com);
    centreOfMassKernel->addArg(forces);  // y, set per call
    centreOfMassKernel->addArg(com);
    readForcesKernel->addArg(cc.getLongForceBuffer());
    readForcesKernel->addArg(cc.getAtomIndexArray());
    readForcesKernel->addArg(particleBead);
    readForcesKernel->addArg(forces);
}

VectorPtr CommonRPYBackend::createVector() {
    CommonVector* v = new CommonVector();
    v->a.initialize<double>(cc, 3 * n, "rpyStateVector");
    cc.clearBuffer(v->a);
    return VectorPtr(v);
}

void CommonRPYBackend::applySettings(const RPYIntegrator& integrator) {
    lanczos = integrator.getNoiseMethod() == "lanczos";
    lanczosTolerance = integrator.getLanczosTolerance();
    singleFactor = usesSingleFactor(integrator.getNoisePrecision(), single || mixed);
}

// --- the Context -------------------------------------------------------------------------------

void CommonRPYBackend::getPositions(ContextImpl&, StateVector& y) { readPositions(data(y)); }

void CommonRPYBackend::readPositions(ComputeArray& y) {
    readPositionsKernel->setArg(mixed ? 4 : 3, y);
    readPositionsKernel->execute(numAtoms);
}

bool CommonRPYBackend::holds(ContextImpl&, const StateVector& y) {
    readPositions(energyPosition);
    return countDifferent(energyPosition, data(y)) == 0;
}

void CommonRPYBackend::writePositions(ComputeArray& y, bool shift) {
    if (shift) {
        centreOfMassKernel->setArg(0, y);
        centreOfMassKernel->execute(reduceSize, reduceSize);
    }
    else
        cc.clearBuffer(com);
    writePositionsKernel->setArg(mixed ? 4 : 3, y);
    writePositionsKernel->execute(numAtoms);
    if (hasVirtualSites)
        cc.getIntegrationUtilities().computeVirtualSites();
}

void CommonRPYBackend::setPositions(ContextImpl&, const StateVector& y) { writePositions(data(y), false); }

void CommonRPYBackend::mobilityTimes(ComputeArray& x, ComputeArray& f, ComputeArray& out) {
    mobilityKernel->setArg(0, x);
    mobilityKernel->setArg(1, f);
    mobilityKernel->setArg(2, out);
    const int groups = std::max(1, std::min((n + tileSize - 1) / tileSize, cc.getNumThreadBlocks()));
    mobilityKernel->execute(groups * tileSize, tileSize);
}

void CommonRPYBackend::velocity(ContextImpl& context, const StateVector& y, StateVector& v) {
    writePositions(data(y), true);
    context.calcForcesAndEnergy(true, false, context.getIntegrator().getIntegrationForceGroups());
    readForcesKernel->execute(numAtoms);
    // the mobility depends on differences only: y itself, not the shifted copy in the Context
    mobilityTimes(data(y), forces, data(v));
}

void CommonRPYBackend::groupEnergies(ContextImpl& context, const StateVector& at, const vector<int>& groups,
                                     vector<double>& energies) {
    // As the Reference backend: at the positions the steps evaluate forces at, one energy-only
    // evaluation per group, then the Context's positions and forces exactly as they were.
    ArrayInterface& posq = cc.getPosq();
    ArrayInterface& force = cc.getLongForceBuffer();
    if (!savedPosq.isInitialized()) {
        savedPosq.initialize(cc, posq.getSize(), posq.getElementSize(), "rpySavedPosq");
        savedForces.initialize(cc, force.getSize(), force.getElementSize(), "rpySavedForces");
        if (mixed)
            savedPosqCorrection.initialize(cc, cc.getPosqCorrection().getSize(),
                                           cc.getPosqCorrection().getElementSize(), "rpySavedPosqCorrection");
    }
    posq.copyTo(savedPosq);
    force.copyTo(savedForces);
    if (mixed)
        cc.getPosqCorrection().copyTo(savedPosqCorrection);
    const int savedGroups = context.getLastForceGroups();
    auto restore = [&]() {
        savedPosq.copyTo(posq);
        savedForces.copyTo(force);
        if (mixed)
            savedPosqCorrection.copyTo(cc.getPosqCorrection());
        context.getLastForceGroups() = savedGroups;
    };
    energies.assign(groups.size(), 0.0);
    try {
        writePositions(data(at), true);
        for (size_t i = 0; i < groups.size(); i++)
            energies[i] = context.calcForcesAndEnergy(false, true, 1 << groups[i]);
    }
    catch (...) {
        restore();
        throw;
    }
    restore();
}

// --- vector operations ---------------------------------------------------------------------------

ComputeKernel& CommonRPYBackend::combineKernel(const string& pattern, int count) {
    auto found = combineKernels.find(pattern);
    if (found != combineKernels.end())
        return found->second;
    // out_i = t_0 + t_1 + ..., added left to right, t_k = c_k * v_k,i ('m') or v_k,i / c_k ('d')
    std::stringstream src;
    src << "KERNEL void combine(GLOBAL double* out";
    for (int k = 0; k < count; k++)
        src << ", GLOBAL const double* v" << k << ", double c" << k;
    src << ") {\n    for (int i = GLOBAL_ID; i < SIZE; i += GLOBAL_SIZE) {\n";
    for (int k = 0; k < count; k++) {
        const string term = pattern[k] == 'd' ? "v" + std::to_string(k) + "[i]/c" + std::to_string(k)
                                              : "c" + std::to_string(k) + "*v" + std::to_string(k) + "[i]";
        src << (k == 0 ? "        double acc = " : "        acc = acc + ") << term << ";\n";
    }
    src << "        out[i] = acc;\n    }\n}\n";
    auto compiled = combinePrograms->find(pattern);
    if (compiled == combinePrograms->end()) {
        std::map<string, string> combineDefines = {{"SIZE", cc.intToString(3 * n)}};
        compiled = combinePrograms->emplace(pattern, cc.compileProgram(src.str(), combineDefines)).first;
    }
    ComputeKernel kernel = compiled->second->createKernel("combine");
    kernel->addArg(forces);
    for (int k = 0; k < count; k++) {
        kernel->addArg(forces);
        kernel->addArg(1.0);
    }
    return combineKernels[pattern] = kernel;
}

void CommonRPYBackend::combine(StateVector& out, std::initializer_list<Term> terms) {
    const int count = (int) terms.size();
    if (count < 1 || count > 8)
        throw OpenMMException("CommonRPYBackend::combine: 1 to 8 terms");
    string pattern;
    for (const Term& t : terms)
        pattern += t.divide ? 'd' : 'm';
    ComputeKernel& kernel = combineKernel(pattern, count);
    kernel->setArg(0, data(out));
    int k = 0;
    for (const Term& t : terms) {
        kernel->setArg(1 + 2 * k, data(*t.v));
        kernel->setArg(2 + 2 * k, t.c);
        k++;
    }
    kernel->execute(3 * n);
}

void CommonRPYBackend::copy(StateVector& out, const StateVector& in) { data(in).copyTo(data(out)); }

void CommonRPYBackend::setZero(StateVector& out) { cc.clearBuffer(data(out)); }

int CommonRPYBackend::countDifferent(ComputeArray& a, ComputeArray& b) {
    countDifferentKernel->setArg(0, a);
    countDifferentKernel->setArg(1, b);
    countDifferentKernel->execute(reduceSize, reduceSize);
    int different = 0;
    counts.download(&different);
    return different;
}

bool CommonRPYBackend::equal(const StateVector& a, const StateVector& b) { return countDifferent(data(a), data(b)) == 0; }

double CommonRPYBackend::norm(const StateVector& v) {
    sumSquaresKernel->setArg(0, data(v));
    sumSquaresKernel->execute(reduceSize, reduceSize);
    double result[3];  // scalars holds 3
    scalars.download(result);
    return std::sqrt(result[0]);
}

double CommonRPYBackend::maxBeadNorm(const StateVector& v) {
    return CommonRPYBackend::checkTry(v, v).errorNorm;  // not a batch copy's checkTry: v is its own
}

int CommonRPYBackend::firstNonFinite(const StateVector& v) {
    firstNonFiniteKernel->setArg(0, data(v));
    firstNonFiniteKernel->execute(reduceSize, reduceSize);
    int first = 0;
    counts.download(&first);
    return first < 3 * n ? first : -1;
}

RPYBackend::TryCheck CommonRPYBackend::checkTry(const StateVector& err, const StateVector& y1) {
    checkTryKernel->setArg(0, data(err));
    checkTryKernel->setArg(1, data(y1));
    checkTryKernel->execute(reduceSize, reduceSize);
    double result[3];
    scalars.download(result);  // the one download of a try
    return tryCheckOf(result);
}

RPYBackend::TryCheck CommonRPYBackend::tryCheckOf(const double result[3]) const {
    const int first = (int) result[2];
    return TryCheck{result[1] == 0.0 ? std::sqrt(result[0]) : std::numeric_limits<double>::infinity(),
                    first < 3 * n ? first : -1};
}

void CommonRPYBackend::download(const StateVector& v, vector<double>& out) { data(v).download(out); }

void CommonRPYBackend::upload(const vector<double>& in, StateVector& v) { data(v).upload(in); }

// --- the kernel --------------------------------------------------------------------------------

std::unique_ptr<RPYBackend> CommonIntegrateRPYStepKernel::createBackend(const System& system,
                                                                        const RPYIntegrator& integrator) {
    cc.initializeContexts();
    ContextSelector selector(cc);
    return std::unique_ptr<RPYBackend>(new CommonRPYBackend(cc, system, integrator));
}

double CommonIntegrateRPYStepKernel::execute(ContextImpl& context, RPYIntegrator& integrator, double targetTime) {
    ContextSelector selector(cc);
    return StepperKernel::execute(context, integrator, targetTime);
}

void CommonIntegrateRPYStepKernel::computeGroupEnergies(ContextImpl& context, const vector<int>& groups,
                                                        vector<double>& energies) {
    ContextSelector selector(cc);
    StepperKernel::computeGroupEnergies(context, groups, energies);
}

void CommonIntegrateRPYStepKernel::createCheckpoint(std::ostream& stream) const {
    ContextSelector selector(cc);
    StepperKernel::createCheckpoint(stream);
}

void CommonIntegrateRPYStepKernel::loadCheckpoint(std::istream& stream) {
    ContextSelector selector(cc);
    StepperKernel::loadCheckpoint(stream);
}
