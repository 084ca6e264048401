// The stepper's checkpoint layout. Version 6 (the counter-based noise stream's key and draw
// counter, appended) is written; versions 5 (the state the stepper keeps in double precision,
// so a device run in mixed or single precision continues bit for bit; its run continues with
// the sequential noise stream it was drawing from), 4
// (without it: the next step starts from the Context's positions), 3 (without
// ito_heun_adaptive's controller memory and queued Wiener increments) and 2 (without
// leimkuhler_matthews's held kick either) still load. The order of the fields is the layout:
// append only.

#include "knotmm/stepper/BinaryIO.h"
#include "knotmm/stepper/Stepper.h"

#include "openmm/OpenMMException.h"

using namespace KnotMM;
using namespace KnotMM::binary;

namespace {
const int CHECKPOINT_VERSION = 6;

void putState(std::ostream& stream, RPYBackend& b, bool have, const StateVector& v) {
    std::vector<double> host;
    if (have)
        b.download(v, host);
    putVector(stream, host);
}

/** Reads a vector; true (and `v` set) if it has 3n numbers. */
bool getState(std::istream& stream, RPYBackend& b, StateVector& v) {
    std::vector<double> host;
    getVector(stream, host);
    if ((int) host.size() != 3 * b.numBeads())
        return false;
    b.upload(host, v);
    return true;
}
} // namespace

void Stepper::createCheckpoint(std::ostream& stream) const {
    RPYBackend& b = work.backend;
    put(stream, CHECKPOINT_VERSION);
    put(stream, (int) work.method);
    put(stream, b.numBeads());
    put(stream, work.counts.evaluations);
    put(stream, work.counts.accepted);
    put(stream, work.counts.rejected);
    put(stream, rk23.errOld);
    put(stream, work.k1.valid);
    putState(stream, b, work.k1.valid, *work.k1.v);
    putState(stream, b, work.k1.valid, *work.k1.positions);
    put(stream, (long long) work.k1.parameters.size());
    for (const auto& p : work.k1.parameters) {
        put(stream, (long long) p.first.size());
        stream.write(p.first.data(), p.first.size());
        put(stream, p.second);
    }
    put(stream, rkc2.haveRho);
    put(stream, rkc2.rho);
    put(stream, rkc2.haveEig);
    putState(stream, b, rkc2.haveEig, *rkc2.eig);
    put(stream, rkc2.stepsSinceRho);
    put(stream, rkc2.lastStages);
    put(stream, rkc2.haveErrOld);
    put(stream, rkc2.errOld);
    put(stream, rkc2.haveHOld);
    put(stream, rkc2.hOld);
    work.noise.writeSequential(stream);
    put(stream, fixed.held.valid);
    putState(stream, b, fixed.held.valid, *fixed.held.kick);
    putState(stream, b, fixed.held.valid, *fixed.held.positions);
    put(stream, brownian.errOld);
    put(stream, (long long) brownian.queue.pending.size());
    for (const auto& entry : brownian.queue.pending) {
        put(stream, entry.first);
        putState(stream, b, true, *entry.second);
    }
    put(stream, haveState);
    putState(stream, b, haveState, *work.y);
    work.noise.writeCounter(stream);
}

void Stepper::loadCheckpoint(std::istream& stream) {
    RPYBackend& b = work.backend;
    int version = 0, savedMethod = 0, savedN = 0;
    get(stream, version);
    get(stream, savedMethod);
    get(stream, savedN);
    if (version < 2 || version > CHECKPOINT_VERSION || savedMethod != (int) work.method ||
        savedN != b.numBeads())
        throw OpenMM::OpenMMException("RPYIntegrator: the checkpoint was written with another method, "
                                      "bead count or plugin version");
    get(stream, work.counts.evaluations);
    get(stream, work.counts.accepted);
    get(stream, work.counts.rejected);
    get(stream, rk23.errOld);
    get(stream, work.k1.valid);
    const bool haveVelocity = getState(stream, b, *work.k1.v);
    const bool haveAt = getState(stream, b, *work.k1.positions);
    work.k1.valid = work.k1.valid && haveVelocity && haveAt;
    long long numParameters = 0;
    get(stream, numParameters);
    work.k1.parameters.clear();
    for (long long i = 0; i < numParameters && stream; i++) {
        long long length = 0;
        get(stream, length);
        if (length < 0 || length > (1 << 20))
            break;
        std::string name(length, ' ');
        stream.read(&name[0], length);
        get(stream, work.k1.parameters[name]);
    }
    get(stream, rkc2.haveRho);
    get(stream, rkc2.rho);
    get(stream, rkc2.haveEig);
    rkc2.haveEig = getState(stream, b, *rkc2.eig) && rkc2.haveEig;
    get(stream, rkc2.stepsSinceRho);
    get(stream, rkc2.lastStages);
    get(stream, rkc2.haveErrOld);
    get(stream, rkc2.errOld);
    get(stream, rkc2.haveHOld);
    get(stream, rkc2.hOld);
    work.noise.readSequential(stream);
    fixed.held.valid = false;
    if (version >= 3) {
        bool held = false;
        get(stream, held);
        const bool haveKick = getState(stream, b, *fixed.held.kick);
        const bool haveAt = getState(stream, b, *fixed.held.positions);
        fixed.held.valid = held && haveKick && haveAt;
    }
    brownian.errOld = 1.0;
    brownian.queue.clear();
    if (version >= 4) {
        get(stream, brownian.errOld);
        long long entries = 0;
        get(stream, entries);
        for (long long i = 0; i < entries && stream; i++) {
            double span = 0.0;
            get(stream, span);
            VectorPtr dw = b.createVector();
            if (!getState(stream, b, *dw))
                throw OpenMM::OpenMMException("RPYIntegrator: the checkpoint's Wiener queue is damaged");
            brownian.queue.pending.emplace_back(span, std::move(dw));
        }
    }
    haveState = false;
    if (version >= 5) {
        bool have = false;
        get(stream, have);
        haveState = getState(stream, b, *work.y) && have;
    }
    if (version >= 6)
        work.noise.readCounter(stream);
    checkPositions = true;  // the Context's positions, restored with it, are compared at the next step
    if (!stream)
        throw OpenMM::OpenMMException("RPYIntegrator: the checkpoint is truncated");
}
