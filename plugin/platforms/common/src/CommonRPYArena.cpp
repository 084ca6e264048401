// A copy's vectors in the batch's arena and its backend (ArenaBackend: what it records for the
// round, what it waits for, what it runs alone on the batch's scratch vectors), and the
// batch's side of those calls (settleCopy, stage, unstage) and of the calls on one copy from
// outside (its positions and checkpoints). The rounds: CommonRPYBatch.cpp.

#include "CommonRPYBatch.h"

#include "knotmm/stepper/NoiseStream.h"
#include "openmm/OpenMMException.h"
#include "openmm/common/ContextSelector.h"

#include <algorithm>
#include <climits>

using namespace OpenMM;
using namespace KnotMM;
using std::vector;

namespace {

// A stepper makes 36 vectors when it is made (every method's), a Brownian copy one more for
// its Cholesky factor's point, and an adaptive one one for each rejected try's kept noise
// (most runs: a few); a copy that makes more grows the arena, doubling it.
const int FIRST_SLOTS_PER_COPY = 40;

} // namespace

CommonVector::~CommonVector() {
    if (arena)
        arena->give(copy, slot);
}

// --- the arena ---------------------------------------------------------------------------------

CopyArena::CopyArena(ComputeContext& cc, int stride, int copies) : cc(cc), stride(stride), freeSlots(copies) {}

int CopyArena::take(int copy) {
    if (!freeSlots[copy].empty()) {
        const int slot = freeSlots[copy].back();
        freeSlots[copy].pop_back();
        return slot;
    }
    if (used == capacity) {
        const int grown = std::max(capacity * 2, (int) freeSlots.size() * FIRST_SLOTS_PER_COPY);
        if ((double) grown * stride > (double) INT_MAX)
            throw OpenMMException("RPYIntegrator: the copies' vectors would need more than 2^31 numbers; "
                                  "run fewer copies in one Context");
        std::unique_ptr<ComputeArray> bigger(new ComputeArray());
        bigger->initialize<double>(cc, (size_t) grown * stride, "rpyCopyArena");
        if (used > 0)
            moveNumbers(*numbers, 0, *bigger, 0, used * stride);
        numbers = std::move(bigger);
        capacity = grown;
    }
    return used++;
}

void CopyArena::moveNumbers(ComputeArray& from, int fromAt, ComputeArray& to, int toAt, int count) {
    move->setArg(0, from);
    move->setArg(1, fromAt);
    move->setArg(2, to);
    move->setArg(3, toAt);
    move->setArg(4, count);
    move->execute(count);
}

// --- a copy's backend ----------------------------------------------------------------------------

ArenaBackend::ArenaBackend(CommonRPYBatch& batch, int copy, ComputeContext& cc, int numBeads,
                           const RPYIntegrator& integrator, const CommonRPYBackend* prototype)
    : BatchedBackend<CommonRPYBackend>(batch, copy, cc, numBeads, integrator, prototype), owner(batch) {}

VectorPtr ArenaBackend::createVector() {
    CommonVector* v = new CommonVector();
    CopyArena& arena = owner.arenaOf();
    v->slot = arena.take(index);
    v->arena = owner.sharedArena();
    v->copy = index;
    v->offset = v->slot * arena.stride;
    DeferredOp zero;  // 3n zeros, in order with the copy's other operations
    zero.pattern = "z";
    zero.out = v->offset;
    owner.defer(index, std::move(zero));
    return VectorPtr(v);
}

void ArenaBackend::combine(StateVector& out, std::initializer_list<Term> terms) {
    const int count = (int) terms.size();
    if (count < 1 || count > 8)
        throw OpenMMException("CommonRPYBackend::combine: 1 to 8 terms");
    DeferredOp op;
    op.out = arenaOffset(out);
    int k = 0;
    for (const Term& t : terms) {
        op.pattern += t.divide ? 'd' : 'm';
        op.in[k] = arenaOffset(*t.v);
        op.c[k] = t.c;
        k++;
    }
    owner.defer(index, std::move(op));
}

void ArenaBackend::copy(StateVector& out, const StateVector& in) {
    combine(out, {times(1.0, in)});  // 1 x: the numbers themselves
}

void ArenaBackend::setZero(StateVector& out) {
    DeferredOp op;
    op.pattern = "z";
    op.out = arenaOffset(out);
    owner.defer(index, std::move(op));
}

RPYBackend::TryCheck ArenaBackend::checkTry(const StateVector& err, const StateVector& y1) {
    if (owner.inFiberOf(index))
        return owner.waitForCheck(index, &err, y1);
    return CommonRPYBackend::checkTry(owner.stage(0, err), owner.stage(1, y1));
}

int ArenaBackend::firstNonFinite(const StateVector& v) {
    if (owner.inFiberOf(index))
        return owner.waitForCheck(index, nullptr, v).nonFinite;
    return CommonRPYBackend::firstNonFinite(owner.stage(0, v));
}

bool ArenaBackend::equal(const StateVector& a, const StateVector& b) {
    return CommonRPYBackend::equal(owner.stage(0, a), owner.stage(1, b));
}

double ArenaBackend::norm(const StateVector& v) { return CommonRPYBackend::norm(owner.stage(0, v)); }

double ArenaBackend::maxBeadNorm(const StateVector& v) { return CommonRPYBackend::maxBeadNorm(owner.stage(0, v)); }

void ArenaBackend::factorNoise(const StateVector& y) {
    if (lanczos || !owner.inFiberOf(index)) {
        factorPending = false;
        CommonRPYBackend::factorNoise(owner.stage(0, y));
        return;
    }
    if (!factorPoint)
        factorPoint = createVector();
    copy(*factorPoint, y);  // recorded: y as it is now, in order with the copy's operations
    factorPending = true;
}

void ArenaBackend::applyNoise(double scale, const StateVector& z, StateVector& out) {
    if (!lanczos && owner.inFiberOf(index)) {
        owner.setNoiseScale(index, scale);
        owner.waitForNoise(index, z, out);
        return;
    }
    if (factorPending) {
        factorPending = false;
        CommonRPYBackend::factorNoise(owner.stage(0, *factorPoint));
    }
    CommonRPYBackend::applyNoise(scale, owner.stage(0, z), owner.scratchVector(1));
    owner.unstage(1, out);
}

void ArenaBackend::normals(NoiseStream& stream, StateVector& out) {
    if (stream.counterBased()) {  // recorded: the key and this draw, as 32-bit halves
        const uint64_t key = stream.key(), draw = stream.takeDraw();
        DeferredOp op;
        op.pattern = "n";
        op.out = arenaOffset(out);
        op.c[0] = (double) (key & 0xffffffffu);
        op.c[1] = (double) (key >> 32);
        op.c[2] = (double) (draw & 0xffffffffu);
        op.c[3] = (double) (draw >> 32);
        owner.defer(index, std::move(op));
        return;
    }
    owner.settleCopy(index);  // before the shared scratch is written: unstage cannot wait then
    CommonRPYBackend::normals(stream, owner.scratchVector(0));
    owner.unstage(0, out);
}

void ArenaBackend::download(const StateVector& v, vector<double>& host) {
    CommonRPYBackend::download(owner.stage(0, v), host);
}

void ArenaBackend::upload(const vector<double>& host, StateVector& v) {
    owner.settleCopy(index);  // before the shared scratch is written: unstage cannot wait then
    CommonRPYBackend::upload(host, owner.scratchVector(0));
    owner.unstage(0, v);
}

// --- the batch's side of a copy's calls ---------------------------------------------------------

void CommonRPYBatch::settleCopy(int copy) {
    if (pending[copy].empty())
        return;
    if (inFiberOf(copy))
        waitForSettle(copy);  // the round launches it with every copy's
    else {
        hostTable.clear();
        launchPending();
    }
}

CommonVector& CommonRPYBatch::stage(int k, const StateVector& v) {
    const CommonVector& from = static_cast<const CommonVector&>(v);
    settleCopy(from.copy);
    arena->moveNumbers(*arena->numbers, from.offset, scratch[k]->a, 0, 3 * n);
    return *scratch[k];
}

void CommonRPYBatch::unstage(int k, StateVector& v) {
    const CommonVector& to = static_cast<const CommonVector&>(v);
    settleCopy(to.copy);
    arena->moveNumbers(scratch[k]->a, 0, *arena->numbers, to.offset, 3 * n);
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
