"""Writhe of known curves, handedness, rotation sense, knot type along a trajectory."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import vortex_knot_positions

from knotmm.analysis import handedness, knot_types, rotation_sense
from knotmm.knots.identify import topoly_available
from knotmm.knots.writhe import writhe


def torus_knot(p, q, n=600, r0=4.3, a=0.05):
    angle = 2 * np.pi * p * np.arange(n) / n
    rho = r0 + a * np.sin(q * angle / p)
    return np.c_[rho * np.cos(angle), rho * np.sin(angle), a * np.cos(q * angle / p)]


@pytest.mark.parametrize("p, q", [(2, 3), (2, 5), (3, 2), (3, 4)])
def test_writhe_of_thin_torus_knots(p, q):
    """On a thin torus the writhe of T(p,q) tends to the crossing number q(p-1)."""
    wr = writhe(torus_knot(p, q))
    assert wr == pytest.approx(q * (p - 1), abs=0.01)
    mirrored = torus_knot(p, q) * [1, 1, -1]
    assert writhe(mirrored) == pytest.approx(-wr, abs=1e-9)


def test_writhe_of_planar_and_moved_curves():
    t = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    ellipse = np.c_[3 * np.cos(t), np.sin(t), np.zeros_like(t)]
    assert writhe(ellipse) == pytest.approx(0.0, abs=1e-12)
    trefoil = torus_knot(2, 3, n=90, a=0.6)
    rot = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))[0]
    rot *= np.sign(np.linalg.det(rot))  # a proper rotation
    moved = trefoil @ rot.T * 2.5 + [1.0, -4.0, 7.0]
    assert writhe(moved) == pytest.approx(writhe(trefoil), rel=1e-9)


def test_handedness_and_rotation_sense_words():
    assert handedness(3.1) == "right"
    assert handedness(-3.1) == "left"
    assert handedness(0.01) is None
    assert rotation_sense(0.002) == "counterclockwise"
    assert rotation_sense(-0.002) == "clockwise"
    assert rotation_sense(0.0) is None


def test_knot_change_found_by_bisection():
    """A fake identifier: type changes at frame 137 of 400."""
    n = 400
    times = np.arange(n) * 0.5
    positions = np.zeros((n, 5, 3))
    positions[:, 0, 0] = np.arange(n)
    calls = []

    def identify(x):
        calls.append(int(x[0, 0]))
        return "3_1" if x[0, 0] < 137 else "0_1"

    kt = knot_types(times, positions, 20, 300, samples=20, identify=identify)
    assert kt.initial == "3_1" and kt.start == "3_1" and kt.end == "0_1"
    assert kt.changed_frame == 137 and kt.changed_at == 68.5
    assert len(set(calls)) == kt.checked_frames < 40


def test_knot_never_changes():
    times = np.arange(50) * 1.0
    kt = knot_types(times, np.zeros((50, 4, 3)), 5, 45, identify=lambda x: "3_1")
    assert kt.changed_at is None and kt.end == "3_1"


def test_no_topoly_gives_null_and_note():
    kt = knot_types(np.arange(10.0), np.zeros((10, 4, 3)), 0, 9, identify=lambda x: None)
    assert (kt.initial, kt.start, kt.end, kt.changed_at) == (None, None, None, None)
    assert "topoly" in kt.notes[0]


@pytest.mark.skipif(not topoly_available(), reason="topoly not installed")
def test_trefoil_unties_with_topoly():
    """Frames 0-29: a trefoil; then a plain ring (the strands passed through each other)."""
    times = np.arange(60) * 0.5
    x = vortex_knot_positions(times, n_beads=60, rho0=2.9, swirl_amplitude=0.5)
    angle = 2 * np.pi * np.arange(60) / 60
    x[30:] = np.c_[3 * np.cos(angle), 3 * np.sin(angle), np.zeros(60)]
    kt = knot_types(times, x, 0, 59, samples=6)
    assert kt.initial == "+3_1" and kt.end == "0_1"  # signed: the right-handed trefoil
    assert kt.changed_frame == 30 and kt.changed_at == 15.0


def _trefoil_then_ring(n_frames: int, change_at: float):
    """A swirling trefoil (frames 0.5 tau_d apart) that is a plain ring from ``change_at``."""
    from knotmm.analysis import RunData

    times = np.arange(n_frames) * 0.5
    x = vortex_knot_positions(times, n_beads=60, rho0=2.9, swirl_amplitude=0.3)
    angle = 2 * np.pi * np.arange(60) / 60
    after = times >= change_at
    ring = np.c_[2.9 * np.cos(angle), 2.9 * np.sin(angle), np.zeros(60)]
    x[after] = ring[None] + x[after].mean(axis=1, keepdims=True)
    return RunData.from_arrays(x, 0.5, {"knot": {"p": 2, "q": 3}, "model": {"bond_length": 0.3}})


@pytest.mark.skipif(not topoly_available(), reason="topoly not installed")
def test_window_ends_before_a_change_of_knot_type():
    """A steady trefoil whose strands pass through each other at t = 150: the periodic
    state ends there, so the window must stop before it (unless --to says otherwise)."""
    from knotmm.analysis import analyze

    data = _trefoil_then_ring(601, 150.0)
    result = analyze(data, knot_samples=12, fit=False)
    assert result.window.t1 < 150.0
    assert result.knots.changed_at == 150.0
    assert any("knot type changed" in n for n in result.notes)
    forced = analyze(data, t_to=200.0, knot_samples=12, fit=False)
    assert forced.window.t1 == 200.0


@pytest.mark.skipif(not topoly_available(), reason="topoly not installed")
def test_early_change_of_knot_type_still_gives_the_whole_run_measures():
    """The strands pass through each other at frame 10, before the 16 frames a window needs:
    the analysis does not fail; the whole-run measures stand and a note says why the window
    may include the change."""
    from knotmm.analysis import analyze

    data = _trefoil_then_ring(121, 5.0)
    result = analyze(data, knot_samples=12, fit=False)
    assert result.knots.changed_at == 5.0
    assert any("before the 16 frames a window needs" in n for n in result.notes)
    assert result.to_dict()["body_frame"]["torus_fraction"] is not None
