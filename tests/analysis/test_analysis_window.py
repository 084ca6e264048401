"""Steady-window detection: transient skipped, collapse detected, overrides honoured."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import vortex_knot_positions

from knotmm.analysis import analyze, steady_window
from knotmm.errors import ConfigError
from knotmm.io.run_data import RunData

DT = 0.5
T_COLLAPSE = 220.0


def collapsing_trajectory(noise=0.02):
    """Grows from rho0 = 3 to 4.3 (time constant 6), collapses to 1.5 at t = 220-225."""
    times = np.arange(601) * DT
    grow = np.exp(-times / 6.0)
    fall = np.clip((times - T_COLLAPSE) / 5.0, 0.0, 1.0)
    rho0 = 4.3 - 1.3 * grow - 2.8 * fall
    amp = 0.5 * (1 - grow) * (1 - 0.5 * fall) + 0.05
    speed = 7.0 + 2.0 * fall  # the compact coil falls faster
    z_com = -np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * DT)])
    x = vortex_knot_positions(
        times,
        rho0=rho0,
        swirl_amplitude=amp,
        tau_swirl=20.0,
        tau_rot=400.0,
        z_com=z_com,
        noise=noise,
    )
    return times, x


@pytest.fixture(scope="module")
def collapsing():
    return collapsing_trajectory()


def test_transient_and_collapse_detected(collapsing):
    times, x = collapsing
    w = steady_window(times, x)
    # fine pass: radius within 1% of 4.3 once 1.3 exp(-t/6) < 0.043, i.e. t > 20.5; the
    # cross-section relaxes at the same rate
    assert 19.5 <= w.t0 <= 30.0
    assert T_COLLAPSE - 1.0 <= w.t1 <= T_COLLAPSE + 2.0
    assert w.end_reason == "collapse"
    assert w.t1 < w.collapse_time <= T_COLLAPSE + 3.0
    assert w.automatic_start and w.automatic_stop
    assert w.levels["radius"]["level"] == pytest.approx(4.3, rel=0.01)
    assert w.levels["speed"]["level"] == pytest.approx(7.0, rel=0.01)


def test_analysis_on_detected_window(collapsing):
    times, x = collapsing
    result = analyze(RunData.from_arrays(x, DT, {"knot": {"p": 2, "q": 3}}), knot_samples=0)
    d = result.to_dict()
    assert d["window"][0] >= 19.5 and d["window"][1] <= T_COLLAPSE + 2.0
    assert d["window_info"]["end_reason"] == "collapse"
    assert d["sedimentation_velocity"] == pytest.approx(7.0, rel=0.01)
    assert d["major_radius"] == pytest.approx(4.3, rel=0.01)
    assert d["tau_swirl"] == pytest.approx(20.0, rel=0.01)


def test_steady_trajectory_uses_everything():
    times = np.arange(201) * DT
    x = vortex_knot_positions(times, noise=0.02)
    w = steady_window(times, x)
    assert (w.start, w.stop) == (0, 200)
    assert w.end_reason == "end of trajectory" and w.collapse_time is None


def test_overrides(collapsing):
    times, x = collapsing
    w = steady_window(times, x, t_from=50.0, t_to=150.2)
    assert (w.t0, w.t1) == (50.0, 150.0)
    assert not w.automatic_start and not w.automatic_stop
    assert w.end_reason == "given"
    # one side given: the other keeps its detected value
    w = steady_window(times, x, t_from=50.0)
    assert w.t0 == 50.0 and w.automatic_stop and w.end_reason == "collapse"
    # start after the collapse: the automatic end moves to the end of the trajectory
    w = steady_window(times, x, t_from=250.0)
    assert (w.t0, w.t1) == (250.0, 300.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"t_from": -5.0}, "--from -5 lies outside"),
        ({"t_to": 1000.0}, "--to 1000 lies outside"),
        ({"t_from": 100.0, "t_to": 50.0}, "must be earlier"),
        ({"t_from": 100.0, "t_to": 102.0}, "holds 5 frames"),
    ],
)
def test_bad_windows(collapsing, kwargs, match):
    times, x = collapsing
    with pytest.raises(ConfigError, match=match):
        steady_window(times, x, **kwargs)


def test_too_short_trajectory():
    times = np.arange(8) * DT
    with pytest.raises(ConfigError, match="8 frames"):
        steady_window(times, vortex_knot_positions(times))


def test_tilting_structure_ends_the_window():
    """The level torus starts to tilt at t = 150, growing exponentially (2 tau_d e-folding)."""
    times = np.arange(501) * DT
    x = vortex_knot_positions(times, noise=0.01)
    com = x.mean(axis=1, keepdims=True)
    angle = 1e-4 * np.exp(np.clip(times - 150.0, 0.0, None) / 2.0)
    angle = np.where(times < 150.0, 0.0, np.minimum(angle, 0.25))
    rel = x - com
    y, z = rel[..., 1].copy(), rel[..., 2].copy()
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    rel[..., 1], rel[..., 2] = c * y - s * z, s * y + c * z
    w = steady_window(times, rel + com)
    # the tilt passes the fine band (0.02 rad) at t = 150 + 2 ln(200) = 160.6; its average
    # over the preceding swirl period (20 tau_d) does at 150 + 2 ln(2000) = 165.2
    assert 155.0 <= w.t1 <= 166.0
    assert w.end_reason.startswith("departure")
    assert w.collapse_time is None


def _turning_arc(times: np.ndarray, speed: float = 3.0) -> np.ndarray:
    """A rigid semicircular arc (30 beads, radius 3 d), its ends on the x axis, falling at
    ``speed`` and turning about its end-to-end line from lying flat (t < 25) to standing
    upright (t > 30): its speed, Rg, end-to-end length (6 d) and angle to the vertical
    (90 deg) never change; only the beads' distance from the vertical axis does."""
    phi = np.linspace(0.0, np.pi, 30)
    local = np.c_[3.0 * np.cos(phi), 3.0 * np.sin(phi), np.zeros(30)]
    local[:, 1] -= local[:, 1].mean()  # turning about the line through its centre of mass
    theta = 0.5 * np.pi * np.clip((times - 25.0) / 5.0, 0.0, 1.0)
    y = local[None, :, 1] * np.cos(theta)[:, None]
    z = local[None, :, 1] * np.sin(theta)[:, None] - speed * times[:, None]
    return np.stack([np.broadcast_to(local[:, 0], y.shape), y, z], axis=-1)


def test_an_open_chain_has_its_own_window_and_no_torus_collapse():
    times = np.arange(161) * 0.25
    x = _turning_arc(times)
    ring = steady_window(times, x)  # read as a torus, it tilts and its "radius" shrinks
    assert ring.t1 <= 25.0 and ring.end_reason in (
        "collapse", "departure: radius", "departure: cross_section", "departure: tilt")
    w = steady_window(times, x, open_chain=True)
    assert (w.t0, w.t1, w.end_reason) == (0.0, 40.0, "end of trajectory")
    assert w.collapse_time is None and "torus" not in w.criterion
    assert set(w.levels) == {"speed", "rg", "end_to_end", "angle"}
    assert w.levels["end_to_end"]["level"] == pytest.approx(6.0)
    assert w.levels["angle"]["level"] == pytest.approx(0.5 * np.pi)
    assert w.levels["speed"]["level"] == pytest.approx(3.0)


def test_a_steady_stretch_too_short_is_widened_with_a_note():
    """Steady only near its end (about 12 frames): the window is widened, and says so."""
    times = np.arange(161) * 0.25
    x = _turning_arc(times)
    x[..., 1] = _turning_arc(np.zeros_like(times))[..., 1]  # lying flat throughout
    speed = 3.0 + 2.0 * np.minimum(times, 39.0)  # speeding up until t = 39
    z_com = -np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * 0.25)])
    x[..., 2] = z_com[:, None]
    w = steady_window(times, x, open_chain=True)
    assert w.stop - w.start + 1 >= 16
    assert any("fewer than the 16" in note and "not steady" in note for note in w.notes)
