"""K copies of one system in one Context (RPYIntegrator.setNumCopies), held to single runs.

The reference is each copy run alone, in a Context of its own (the plugin's single path,
itself held to the Python integrators elsewhere): a copy must follow it to rounding, take
the same steps, keep its own step control beside a copy that needs small steps, not feel
another copy moved far away, and fail alone.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from threadpoolctl import threadpool_limits

from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system, copies_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot

N, K = 30, 3
PLATFORMS = plugin_platforms()  # Reference, CPU, OpenCL (pocl here), CUDA where a GPU is


def _context(system, integ, platform):
    """A Context on ``platform``; a device platform in double precision."""
    properties = {"Precision": "double"} if platform in DEVICE_PLATFORMS else {}
    return openmm.Context(system, integ, openmm.Platform.getPlatformByName(platform), properties)


def _starts(k=K, seed=0):
    x0 = torus_knot(2, 3, N)
    rng = np.random.default_rng(seed)
    return [x0 + 0.05 * rng.standard_normal(x0.shape) for _ in range(k)]


DETERMINISTIC = ("rk23", "rkc2", "heun")


def _integrator(method, seed=0, threads=1, step=None):
    if method in DETERMINISTIC:
        return RPYIntegrator(step or 0.01, method, threads=threads)
    return RPYIntegrator(step or 0.002, method, threads=threads, kT=0.5, seed=seed)


def _single(x, method, platform, seed=0, step=None):
    integ = _integrator(method, seed, step=step)
    ctx = _context(chain_system(x), integ, platform)
    ctx.setPositions(x)
    return integ, ctx


def _batch(starts, method, platform, singles=None, threads=1, apart=True, step=None):
    """The copies on a grid (``apart``, a System with knotmm's NonbondedForce) or in one
    place (``copies_system``'s interaction groups)."""
    k = len(starts)
    integ = _integrator(method, threads=threads, step=step)
    integ.setNumCopies(k)
    integ.setCopiesApart(apart)
    x = np.vstack(starts)
    system = (chain_system(x, layout=ChainLayout((N,) * k, (True,) * k)) if apart
              else copies_system(starts[0], ChainModel(), ChainLayout.ring(N), k))
    ctx = _context(system, integ, platform)
    ctx.setPositions(x)
    for c, start in enumerate(starts):
        integ.setCopyPositions(c, start.ravel().tolist())
        integ.setCopyTime(c, 0.0)
        if singles is not None:  # the copy's state (seed, step size) is its single run's
            integ.setCopyState(c, singles[c][0].getIntegratorState())
    return integ, ctx


def _positions(ctx):
    return ctx.getState(getPositions=True).getPositions(asNumpy=True)._value


def _copy(integ, c):
    return np.array(integ.getCopyPositions(c)).reshape(-1, 3)


def _accepted(integ, c, method, platform):
    """Copy c's accepted steps: its state loaded into a single integrator of its own."""
    probe, _ctx = _single(_copy(integ, c), method, platform)
    probe.setIntegratorState(integ.getCopyState(c))
    return probe.getNumAcceptedSteps()


def _follow_single_runs(method, platform, apart=True, duration=None, step=None):
    """Step K copies and their K single runs to ``duration``; hold each copy to its run."""
    starts = _starts()
    singles = [_single(x, method, platform, seed=10 + c, step=step) for c, x in enumerate(starts)]
    batch, _ = _batch(starts, method, platform, singles, apart=apart, step=step)
    duration = duration or (1.0 if method in DETERMINISTIC else 0.2)
    for integ, _ctx in singles:
        integ.stepTo(duration)
    assert batch.stepCopiesTo([duration] * K, 1e9)
    for c, (integ, ctx) in enumerate(singles):
        assert batch.getCopyTime(c) == duration
        assert batch.getCopyFaultKind(c) == ""
        # to rounding: the Reference platform and a device in double, the CPU one's float
        # forces; on a device the forces are summed in fixed point, in any order, so copies
        # in one place follow their single runs to 5e-13 d (pocl), on the grid to 1e-9 d
        tol = {"Reference": 1e-9, "CPU": 1e-4}.get(platform, 1e-8 if apart else 1e-11)
        np.testing.assert_allclose(_copy(batch, c), _positions(ctx), rtol=0, atol=tol)
        if platform != "CPU":  # the same steps, one by one
            assert _accepted(batch, c, method, platform) == integ.getNumAcceptedSteps()
    # the copies are different runs (their starts, their noise)
    assert np.abs(_copy(batch, 0) - _copy(batch, 1)).max() > 1e-3
    return singles


@pytest.mark.parametrize("apart", [True, False])
@pytest.mark.parametrize("platform", PLATFORMS)
@pytest.mark.parametrize("method", ["rk23", "ito_heun", "ito_heun_adaptive"])
def test_each_copy_follows_its_single_run(method, platform, apart):
    _follow_single_runs(method, platform, apart)


DEVICES = [p for p in PLATFORMS if p in DEVICE_PLATFORMS]


@pytest.mark.parametrize("platform", DEVICES)
@pytest.mark.parametrize("method", ["rkc2", "heun", "euler_maruyama", "leimkuhler_matthews"])
def test_on_a_device_every_method_s_copies_follow_their_single_runs(method, platform):
    # a device batch records the copies' vector operations and launches them for all copies
    # at once; the methods' other calls (norms of rkc2's spectral radius, the fixed steps'
    # finiteness checks, the noise) run for one copy at a time between them
    _follow_single_runs(method, platform, duration=0.5 if method in DETERMINISTIC else 0.1)


@pytest.mark.parametrize("platform", DEVICES)
def test_on_a_device_copies_that_reject_many_tries_follow_their_single_runs(platform):
    # a first step of 1000 ps: every copy's tries are rejected until about 1e-4 ps, and each
    # rejected try's noise is kept (a vector made mid-step, one more per rejection), so the
    # copies' vectors outgrow the arena's first size and it grows under pending operations.
    # In one place: on the grid, the tries' wild positions would set its spacing
    singles = _follow_single_runs("ito_heun_adaptive", platform, apart=False, duration=0.05,
                                  step=1e3)
    assert all(integ.getNumRejectedSteps() >= 5 for integ, _ctx in singles)


def test_a_copy_that_needs_small_steps_does_not_slow_the_others():
    starts = _starts()
    squeezed = starts[0].copy()
    squeezed[10] = squeezed[20] + [0.45, 0.0, 0.0]  # deep in another bead's steric core
    starts[0] = squeezed
    singles = [_single(x, "rk23", "Reference") for x in starts]
    batch, _ = _batch(starts, "rk23", "Reference", singles)
    for integ, _ctx in singles:
        integ.stepTo(0.5)
    assert batch.stepCopiesTo([0.5] * K, 1e9)
    counts = [_accepted(batch, c, "rk23", "Reference") for c in range(K)]
    assert counts == [integ.getNumAcceptedSteps() for integ, _ in singles]
    assert counts[0] >= 1.5 * max(counts[1:])  # the squeezed copy took many more steps


@pytest.mark.parametrize("platform", [p for p in PLATFORMS if p != "Reference"])
def test_in_one_place_a_copy_does_not_feel_what_the_others_do(platform):
    # copies_system: a copy's forces are its own; copy 0 takes the same steps whether the
    # others move, stand still or were never given a target
    starts = _starts(4)
    singles = [_single(x, "ito_heun_adaptive", platform, seed=30 + c)
               for c, x in enumerate(starts)]
    runs = []
    for targets in ([0.3] * 4, [0.3, 0.0, 0.0, 0.0], [0.3, 0.1, 0.25, 0.0]):
        batch, ctx = _batch(starts, "ito_heun_adaptive", platform, singles, apart=False)
        assert batch.getCopySpacing() == 0.0
        batch.stepCopiesTo(targets, 1e9)
        runs.append((_copy(batch, 0), ctx))
    for positions, _ctx in runs[1:]:
        np.testing.assert_array_equal(positions, runs[0][0])
    # and with copies_system's grouped steric term the copies see each other in no force
    assert np.abs(_copy(batch, 0) - _copy(batch, 3)).max() > 1e-3


@pytest.mark.parametrize("platform", PLATFORMS)
def test_moving_one_copy_far_away_changes_no_other(platform):
    starts = _starts()
    moved = [starts[0] + [400.0, -300.0, 1000.0], *starts[1:]]
    a, _actx = _batch(starts, "rk23", platform)  # (a Context kept while its integrator steps)
    b, _bctx = _batch(moved, "rk23", platform)
    assert a.stepCopiesTo([1.0] * K, 1e9) and b.stepCopiesTo([1.0] * K, 1e9)
    for c in range(1, K):
        np.testing.assert_array_equal(_copy(a, c), _copy(b, c))
    # the moved copy itself: its place is rounded otherwise (float forces on the CPU platform)
    tol = 1e-4 if platform == "CPU" else 1e-9
    np.testing.assert_allclose(_copy(b, 0) - [400.0, -300.0, 1000.0], _copy(a, 0), atol=tol)


@pytest.mark.parametrize("platform", PLATFORMS)
def test_a_copy_that_fails_leaves_the_others_going(platform):
    starts = _starts()
    broken = starts[1].copy()
    broken[5] = broken[15]  # two beads at one point: the mobility has no Cholesky factor
    starts[1] = broken
    batch, _ = _batch(starts, "ito_heun", platform)
    assert batch.stepCopiesTo([0.1] * K, 1e9)  # every copy that has not failed got there
    assert batch.getCopyFaultKind(1) in ("not_positive_definite", "non_finite")
    assert batch.getCopyFaultMessage(1)
    assert batch.getCopyTime(1) == 0.0
    np.testing.assert_array_equal(_copy(batch, 1), broken)  # its last good state
    for c in (0, 2):
        assert batch.getCopyTime(c) == pytest.approx(0.1) and batch.getCopyFaultKind(c) == ""


@pytest.mark.parametrize("platform", ["Reference", *DEVICES])
def test_threads_share_out_the_copies_and_change_no_number(platform):
    # the host's share of a round: the mobility products and Cholesky factors of the copies
    # (Reference), the Cholesky factors and noise products of a device's copies
    starts = _starts(4)
    singles = [_single(x, "ito_heun_adaptive", platform, seed=20 + c)
               for c, x in enumerate(starts)]
    one, _one_ctx = _batch(starts, "ito_heun_adaptive", platform, singles, apart=False)
    two, _two_ctx = _batch(starts, "ito_heun_adaptive", platform, singles, threads=2,
                           apart=False)
    with threadpool_limits(limits=1, user_api="blas"):  # LAPACK's own threads round otherwise
        assert one.stepCopiesTo([0.2] * 4, 1e9) and two.stepCopiesTo([0.2] * 4, 1e9)
    for c in range(4):
        np.testing.assert_array_equal(_copy(two, c), _copy(one, c))


@pytest.mark.parametrize("platform", [p for p in PLATFORMS if p != "CPU"])
def test_a_budget_ends_a_call_between_steps_and_changes_no_step(platform):
    starts = _starts()
    whole, _wctx = _batch(starts, "rk23", platform)
    parts, _pctx = _batch(starts, "rk23", platform)
    assert whole.stepCopiesTo([1.0] * K, 1e9)
    calls = 1
    while not parts.stepCopiesTo([1.0] * K, 0.0):  # a step per copy per call
        calls += 1
    assert calls > 10
    for c in range(K):
        np.testing.assert_array_equal(_copy(parts, c), _copy(whole, c))


def test_the_integrator_state_carries_a_run_on_bit_for_bit():
    x = _starts(1)[0]
    a, actx = _single(x, "ito_heun_adaptive", "Reference", seed=3)
    b, bctx = _single(x, "ito_heun_adaptive", "Reference", seed=99)
    a.stepTo(0.1)
    b.setIntegratorState(a.getIntegratorState())  # a's noise stream, step size, cache
    bctx.setPositions(_positions(actx))
    bctx.setTime(0.1)
    a.stepTo(0.2)
    b.stepTo(0.2)
    np.testing.assert_array_equal(_positions(actx), _positions(bctx))


def test_copies_refuse_what_they_cannot_do():
    integ = _integrator("rk23")
    integ.setNumCopies(4)
    layout = ChainLayout((N,) * 3, (True,) * 3)
    x = np.vstack(_starts())
    with pytest.raises(openmm.OpenMMException, match="numCopies must divide"):
        openmm.Context(chain_system(x, layout=layout), integ,
                       openmm.Platform.getPlatformByName("Reference"))
    batch, _ctx = _batch(_starts(), "rk23", "Reference")
    for call in (lambda: batch.step(1), lambda: batch.stepTo(1.0)):
        with pytest.raises(openmm.OpenMMException, match="stepCopiesTo"):
            call()
    with pytest.raises(openmm.OpenMMException, match="2 targets for 3 copies"):
        batch.stepCopiesTo([1.0] * 2, 1.0)
    with pytest.raises(openmm.OpenMMException, match="out of range"):
        batch.getCopyTime(3)
    single, _sctx = _single(_starts(1)[0], "rk23", "Reference")
    with pytest.raises(openmm.OpenMMException, match="setNumCopies"):
        single.getCopyTime(0)
