#include "knotmm/RPYIntegrator.h"
#include "knotmm/RPYKernels.h"
#include "knotmm/RPYMethods.h"
#include "knotmm/RPYStepFault.h"

#include "openmm/Context.h"
#include "openmm/OpenMMException.h"
#include "openmm/internal/ContextImpl.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <istream>
#include <limits>
#include <ostream>
#include <sstream>

using namespace OpenMM;
using namespace KnotMM;

namespace {


void requirePositive(double value, const char* name, const char* hint) {
    if (!(value > 0) || !std::isfinite(value))
        throw OpenMMException(std::string(name) + "=" + formatNumber(value) + ": must be a finite number > 0" + hint);
}

// Checkpoint tag of the integrator's own part (changes when the layout changes).
const int CHECKPOINT_VERSION = 1;

} // namespace

RPYIntegrator::RPYIntegrator(double stepSize, const std::string& method, double errorTolerance)
    : method(method), noiseMethod("cholesky"), noisePrecision("auto"), lanczosTolerance(1e-6), errorTolerance(errorTolerance), beadDiameter(1.0), mobility(1.0),
      thermalEnergy(0.0), minStepSize(1e-7), maxStepSize(1.0), randomSeed(0), numThreads(1) {
    rpyMethodInfo(method);  // throws for an unknown name
    requirePositive(stepSize, "stepSize", " (in ps = tau_d)");
    requirePositive(errorTolerance, "errorTolerance", " (in nm = d)");
    setStepSize(stepSize);
    setConstraintTolerance(1e-5);
}

bool RPYIntegrator::isAdaptive() const { return rpyMethodInfo(method).adaptive; }

bool RPYIntegrator::isStochastic() const { return rpyMethodInfo(method).stochastic; }

namespace {
std::string stochasticNames() {
    std::string names;
    for (const RPYMethodInfo& m : rpyMethodTable())
        if (m.stochastic)
            names += (names.empty() ? "" : ", ") + std::string(m.name);
    return names;
}
} // namespace

void RPYIntegrator::setMethod(const std::string& name) {
    const RPYMethodInfo& info = rpyMethodInfo(name);  // throws for an unknown name
    if (thermalEnergy > 0 && !info.stochastic)
        throw OpenMMException("method='" + name + "': deterministic, but thermalEnergy=" + formatNumber(thermalEnergy) +
                              " > 0; use one of " + stochasticNames() + ", or set thermalEnergy 0 first");
    if (context != nullptr && numCopies > 1)
        throw OpenMMException("method: an integrator of several copies keeps its method once its Context is created");
    method = name;
    if (context == nullptr || !kernelReady)
        return;
    if (isAdaptive())  // as initialize(): never start above the largest step
        setStepSize(std::min(getStepSize(), maxStepSize));
    kernel.getAs<IntegrateRPYStepKernel>().initialize(context->getSystem(), *this);
}

void RPYIntegrator::setErrorTolerance(double tol) {
    requirePositive(tol, "errorTolerance", " (in nm = d)");
    errorTolerance = tol;
}

void RPYIntegrator::setBeadDiameter(double d) {
    requirePositive(d, "beadDiameter", " (in nm = d)");
    if (owner != nullptr)
        throw OpenMMException("beadDiameter: set it before the Context is created");
    beadDiameter = d;
}

void RPYIntegrator::setMobility(double mu0) {
    requirePositive(mu0, "mobility", " (single-bead mobility mu0, in nm/(ps kJ/mol/nm))");
    if (owner != nullptr)
        throw OpenMMException("mobility: set it before the Context is created");
    mobility = mu0;
}

void RPYIntegrator::setThermalEnergy(double kT) {
    if (!(kT >= 0) || !std::isfinite(kT))
        throw OpenMMException("thermalEnergy=" + formatNumber(kT) + ": must be >= 0 (kT in kJ/mol = F0 d; 0 is deterministic)");
    if (kT > 0 && !isStochastic())
        throw OpenMMException("thermalEnergy=" + formatNumber(kT) + ": method '" + method +
                              "' is deterministic; use one of " + stochasticNames() + " for kT > 0");
    thermalEnergy = kT;
}

void RPYIntegrator::setNoiseMethod(const std::string& name) {
    if (name != "cholesky" && name != "lanczos")
        throw OpenMMException("noiseMethod='" + name + "': expected 'cholesky' or 'lanczos'");
    noiseMethod = name;
}

void RPYIntegrator::setNoisePrecision(const std::string& precision) {
    if (precision != "auto" && precision != "single" && precision != "double")
        throw OpenMMException("noisePrecision='" + precision + "': expected 'auto', 'single' or 'double'");
    noisePrecision = precision;
}

void RPYIntegrator::setLanczosTolerance(double tol) {
    requirePositive(tol, "lanczosTolerance", " (relative change between Lanczos iterates)");
    lanczosTolerance = tol;
}

void RPYIntegrator::setRandomNumberSeed(int seed) {
    if (owner != nullptr)
        throw OpenMMException("randomNumberSeed: set it before the Context is created "
                              "(the noise stream is seeded once)");
    randomSeed = seed;
}

void RPYIntegrator::setMinimumStepSize(double h) {
    requirePositive(h, "minimumStepSize", " (in ps)");
    minStepSize = h;
}

void RPYIntegrator::setMaximumStepSize(double h) {
    requirePositive(h, "maximumStepSize", " (in ps)");
    maxStepSize = h;
}

void RPYIntegrator::setNumThreads(int n) {
    if (n < 1)
        throw OpenMMException("numThreads=" + std::to_string(n) + ": must be >= 1");
    numThreads = n;
}

void RPYIntegrator::setSpectralRadiusStartVector(const std::vector<Vec3>& v) {
    if (owner != nullptr)
        throw OpenMMException("spectralRadiusStartVector: set it before the Context is created");
    rkcStart = v;
}

void RPYIntegrator::initialize(ContextImpl& contextRef) {
    if (owner != nullptr && &contextRef.getOwner() != owner)
        throw OpenMMException("This Integrator is already bound to a context");
    if (!rkcStart.empty()) {
        int beads = 0;
        const System& system = contextRef.getSystem();
        for (int i = 0; i < system.getNumParticles(); i++)
            beads += system.isVirtualSite(i) ? 0 : 1;
        if ((int) rkcStart.size() != beads)
            throw OpenMMException("spectralRadiusStartVector: " + std::to_string(rkcStart.size()) +
                                  " vectors given, expected one per bead (" +
                                  std::to_string(beads) + ")");
    }
    if (thermalEnergy > 0 && !isStochastic())
        throw OpenMMException("thermalEnergy > 0 needs one of " + stochasticNames() + ", not " + method);
    if (isAdaptive())  // as knotmm's adaptive integrators: never start above the largest step
        setStepSize(std::min(getStepSize(), maxStepSize));
    context = &contextRef;
    owner = &contextRef.getOwner();
    kernel = context->getPlatform().createKernel(IntegrateRPYStepKernel::Name(), contextRef);
    kernel.getAs<IntegrateRPYStepKernel>().initialize(contextRef.getSystem(), *this);
    kernelReady = true;
}

void RPYIntegrator::cleanup() {
    kernelReady = false;
    kernel = Kernel();
}

std::vector<std::string> RPYIntegrator::getKernelNames() {
    return {IntegrateRPYStepKernel::Name()};
}

void RPYIntegrator::checkInitialized() const {
    if (context == nullptr || !kernelReady)
        throw OpenMMException("RPYIntegrator: not bound to a Context yet");
}

void RPYIntegrator::stateChanged(State::DataType changed) {
    if (changed & State::Positions)
        positionsVersion++;
}

void RPYIntegrator::takeStep(double targetTime) {
    // Inside a CompoundIntegrator the other integrators move the positions without a
    // stateChanged(): treat every step as after an outside change (the stepper then compares
    // the Context's positions with its state and keeps the state while they are unchanged).
    if (&context->getIntegrator() != this)
        positionsVersion++;
    // Barostats, thermostats etc. could change the state; then cached velocities are stale.
    if (context->updateContextState())
        kernel.getAs<IntegrateRPYStepKernel>().invalidateCache();
    kernel.getAs<IntegrateRPYStepKernel>().execute(*context, *this, targetTime);
}

void RPYIntegrator::step(int steps) {
    checkInitialized();
    checkSingle("step");
    for (int i = 0; i < steps; i++)
        takeStep(std::numeric_limits<double>::infinity());
}

void RPYIntegrator::checkTarget(double time) const {
    const double now = context->getTime();
    if (!std::isfinite(time))
        throw OpenMMException("stepTo: time=" + formatNumber(time) + " is not a finite number of ps");
    // the landing rule (RPYMethods.h): a time within the slack counts as reached
    if (time < now - landingSlack(time))
        throw OpenMMException("stepTo: time=" + formatNumber(time) + " ps is earlier than the Context's time " +
                              formatNumber(now) + " ps; overdamped steps only go forward");
}

void RPYIntegrator::stepTo(double time) {
    checkInitialized();
    checkSingle("stepTo");
    checkTarget(time);
    const double slack = landingSlack(time);
    while (context->getTime() < time - slack)
        takeStep(time);
}

bool RPYIntegrator::stepToWithin(double time, double maxSeconds) {
    checkInitialized();
    checkSingle("stepToWithin");
    if (!(maxSeconds >= 0))
        throw OpenMMException("stepToWithin: maxSeconds=" + formatNumber(maxSeconds) +
                              ": must be >= 0 (seconds of wall-clock time; +infinity for no limit)");
    checkTarget(time);
    const double slack = landingSlack(time);
    const auto start = std::chrono::steady_clock::now();
    while (context->getTime() < time - slack) {
        takeStep(time);  // the same call stepTo makes: the budget never changes a step
        const std::chrono::duration<double> spent = std::chrono::steady_clock::now() - start;
        if (spent.count() >= maxSeconds)
            return !(context->getTime() < time - slack);
    }
    return true;
}

std::vector<double> RPYIntegrator::getGroupEnergies(const std::vector<int>& groups) {
    checkInitialized();
    for (int g : groups)
        if (g < 0 || g > 31)
            throw OpenMMException("groups: force group " + std::to_string(g) +
                                  " is out of range; force groups are 0 to 31");
    std::vector<double> energies;
    kernel.getAs<IntegrateRPYStepKernel>().computeGroupEnergies(*context, groups, energies);
    return energies;
}

long long RPYIntegrator::getNumForceEvaluations() const {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().getNumForceEvaluations();
}

long long RPYIntegrator::getNumAcceptedSteps() const {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().getNumAcceptedSteps();
}

long long RPYIntegrator::getNumRejectedSteps() const {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().getNumRejectedSteps();
}

int RPYIntegrator::getLastStages() const {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().getLastStages();
}

double RPYIntegrator::estimateSpectralRadius() {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().estimateSpectralRadius(*context, *this);
}

double RPYIntegrator::getSpectralRadius() const {
    checkInitialized();
    return kernel.getAs<IntegrateRPYStepKernel>().getSpectralRadius();
}

void RPYIntegrator::createCheckpoint(std::ostream& stream) const {
    writeStateHeader(stream, getStepSize());
    kernel.getAs<IntegrateRPYStepKernel>().createCheckpoint(stream);
}

void RPYIntegrator::loadCheckpoint(std::istream& stream) {
    setStepSize(readStateHeader(stream));
    kernel.getAs<IntegrateRPYStepKernel>().loadCheckpoint(stream);
}

std::string RPYIntegrator::getIntegratorState() const {
    checkInitialized();
    std::ostringstream stream(std::ios::binary);
    createCheckpoint(stream);
    return stream.str();
}

void RPYIntegrator::setIntegratorState(const std::string& state) {
    checkInitialized();
    std::istringstream stream(state, std::ios::binary);
    loadCheckpoint(stream);
}

// --- copies --------------------------------------------------------------------------------------

void RPYIntegrator::setNumCopies(int copies) {
    if (owner != nullptr)
        throw OpenMMException("numCopies: set it before the Context is created");
    if (copies < 1)
        throw OpenMMException("numCopies=" + std::to_string(copies) + ": must be at least 1");
    numCopies = copies;
}

void RPYIntegrator::setCopiesApart(bool apart) {
    if (owner != nullptr)
        throw OpenMMException("copiesApart: set it before the Context is created");
    copiesApart = apart;
}

RPYCopies& RPYIntegrator::copies() const {
    checkInitialized();
    RPYCopies* c = kernel.getAs<IntegrateRPYStepKernel>().getCopies();
    if (c == nullptr)
        throw OpenMMException("RPYIntegrator: this integrator holds one system (numCopies = 1); call "
                              "setNumCopies(K) before the Context is created");
    return *c;
}

void RPYIntegrator::checkSingle(const char* what) const {
    if (numCopies > 1)
        throw OpenMMException(std::string("RPYIntegrator: ") + what + " moves one system; this one holds " +
                              std::to_string(numCopies) + " copies: use stepCopiesTo");
}

namespace {
void checkCopy(const RPYCopies& c, int copy) {
    if (copy < 0 || copy >= c.numCopies())
        throw OpenMMException("copy " + std::to_string(copy) + ": out of range; the copies are 0 to " +
                              std::to_string(c.numCopies() - 1));
}
} // namespace

bool RPYIntegrator::stepCopiesTo(const std::vector<double>& targets, double maxSeconds) {
    RPYCopies& c = copies();
    if ((int) targets.size() != c.numCopies())
        throw OpenMMException("stepCopiesTo: " + std::to_string(targets.size()) + " targets for " +
                              std::to_string(c.numCopies()) + " copies");
    if (!(maxSeconds >= 0))
        throw OpenMMException("stepCopiesTo: maxSeconds=" + formatNumber(maxSeconds) + ": must be >= 0");
    for (int k = 0; k < c.numCopies(); k++) {
        if (!std::isfinite(targets[k]))
            throw OpenMMException("stepCopiesTo: the target of copy " + std::to_string(k) + " is not finite");
        if (targets[k] < c.getTime(k) - landingSlack(targets[k]))
            throw OpenMMException("stepCopiesTo: the target of copy " + std::to_string(k) + ", " +
                                  formatNumber(targets[k]) + " ps, is earlier than its time " +
                                  formatNumber(c.getTime(k)) + " ps");
    }
    return c.stepTo(*context, *this, targets, maxSeconds);
}

std::vector<double> RPYIntegrator::getCopyPositions(int copy) const {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    return c.getPositions(copy);
}

void RPYIntegrator::setCopyPositions(int copy, const std::vector<double>& positions) {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    if ((int) positions.size() != 3 * c.beadsPerCopy())
        throw OpenMMException("setCopyPositions: " + std::to_string(positions.size()) + " numbers, expected " +
                              std::to_string(3 * c.beadsPerCopy()) + " (3 per bead)");
    for (double x : positions)
        if (!std::isfinite(x))
            throw OpenMMException("setCopyPositions: a position is not finite");
    c.setPositions(copy, positions);
}

double RPYIntegrator::getCopyTime(int copy) const {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    return c.getTime(copy);
}

void RPYIntegrator::setCopyTime(int copy, double time) {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    if (!std::isfinite(time))
        throw OpenMMException("setCopyTime: the time is not finite");
    c.setTime(copy, time);
}

std::string RPYIntegrator::getCopyState(int copy) const {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    std::ostringstream stream(std::ios::binary);
    c.createCheckpoint(copy, stream);
    return stream.str();
}

void RPYIntegrator::setCopyState(int copy, const std::string& state) {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    std::istringstream stream(state, std::ios::binary);
    c.loadCheckpoint(copy, stream);
}

std::string RPYIntegrator::getCopyFaultKind(int copy) const {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    return c.faultKind(copy);
}

std::string RPYIntegrator::getCopyFaultMessage(int copy) const {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    return c.faultMessage(copy);
}

void RPYIntegrator::clearCopyFault(int copy) {
    RPYCopies& c = copies();
    checkCopy(c, copy);
    c.clearFault(copy);
}

double RPYIntegrator::getCopySpacing() const { return copies().spacing(); }

void RPYIntegrator::writeStateHeader(std::ostream& stream, double stepSize) {
    stream.write((const char*) &CHECKPOINT_VERSION, sizeof(int));
    stream.write((const char*) &stepSize, sizeof(double));
}

double RPYIntegrator::readStateHeader(std::istream& stream) {
    int version = 0;
    double h = 0;
    stream.read((char*) &version, sizeof(int));
    if (version != CHECKPOINT_VERSION)
        throw OpenMMException("RPYIntegrator: checkpoint was written by another version of the plugin");
    stream.read((char*) &h, sizeof(double));
    return h;
}
