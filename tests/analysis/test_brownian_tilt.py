"""Tilt of the torus against gravity and the flips of a Brownian run (knotmm.analysis.tilt)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from knotmm.analysis.tilt import find_flips, planar_winding, ring_normal, tilt_analysis, torus_tilt
from knotmm.shapes import torus_knot


def rotation_x(angle_deg):
    a = math.radians(angle_deg)
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def circle(n=30, radius=3.0):
    t = 2 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)], axis=1)


def test_flat_ring_orientation():
    ring = circle()  # counterclockwise seen from above
    np.testing.assert_allclose(ring_normal(ring), [0, 0, 1], atol=1e-12)
    assert torus_tilt(ring) == pytest.approx(0.0, abs=1e-6)
    assert torus_tilt(ring[::-1]) == pytest.approx(180.0, abs=1e-6)  # clockwise
    assert torus_tilt(ring[::-1], signed=False) == pytest.approx(0.0, abs=1e-6)
    assert torus_tilt(ring + [5.0, -2.0, 40.0]) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("angle", [0.0, 20.0, 60.0, 89.0, 91.0, 135.0, 180.0])
def test_tilted_ring(angle):
    ring = circle() @ rotation_x(angle).T
    assert torus_tilt(ring) == pytest.approx(angle, abs=1e-6)
    assert torus_tilt(ring, signed=False) == pytest.approx(min(angle, 180 - angle), abs=1e-6)


def test_torus_knot_template_is_horizontal_and_turning_it_over_flips_it():
    x = torus_knot(2, 3, 90)
    assert torus_tilt(x) < 1.0
    # turning the chain over (rotation by 180 degrees about x) takes the tilt to 180
    assert torus_tilt(x @ rotation_x(180.0).T) > 179.0
    # the mirror image z -> -z keeps the circulation and the axis: still horizontal
    assert torus_tilt(x * [1, 1, -1]) < 1.0


def test_frames_are_vectorised():
    frames = np.array([circle() @ rotation_x(a).T for a in (0.0, 45.0, 170.0)])
    np.testing.assert_allclose(torus_tilt(frames), [0.0, 45.0, 170.0], atol=1e-6)
    assert ring_normal(frames).shape == (3, 3)
    with pytest.raises(ValueError, match="positions"):
        torus_tilt(np.zeros((4, 2)))


def test_find_flips_with_hysteresis():
    tilt = np.array([5, 10, 70, 95, 80, 40, 100, 130, 170, 150, 110, 100, 50, 10, 20.0])
    times = 0.5 * np.arange(tilt.size)
    flips = find_flips(tilt, times, band=30.0)
    # 95 and 100 stay inside the band (60..120): not flips; 130 completes one, 50 the next
    assert flips.count == 2
    np.testing.assert_array_equal(flips.frames, [7, 12])
    np.testing.assert_allclose(flips.times, [3.5, 6.0])
    np.testing.assert_array_equal(flips.directions, [1, -1])
    assert flips.fraction_down == pytest.approx(7 / 15)  # 95, 100, 130, 170, 150, 110, 100
    assert flips.to_dict()["count"] == 2
    assert find_flips(np.full(10, 10.0)).count == 0
    assert find_flips(np.full(3, 90.0)).notes
    with pytest.raises(ValueError, match="band"):
        find_flips(tilt, band=95.0)


def test_flip_of_a_turning_ring():
    angles = np.concatenate([np.linspace(0, 180, 50), np.linspace(180, 0, 50)])
    frames = np.array([circle() @ rotation_x(a).T for a in angles])
    flips = find_flips(torus_tilt(frames))
    assert flips.count == 2 and list(flips.directions) == [1, -1]


def test_find_flips_skips_invalid_frames():
    tilt = np.array([10.0, 170.0, 10.0, 170.0, 10.0])
    assert find_flips(tilt).count == 4
    flips = find_flips(tilt, valid=[True, False, True, False, True])
    assert flips.count == 0 and flips.fraction_down == 0.0
    assert find_flips(tilt, valid=np.zeros(5, bool)).notes
    with pytest.raises(ValueError, match="valid"):
        find_flips(tilt, valid=[True])


def test_planar_winding():
    assert planar_winding(circle()) == pytest.approx(1.0, rel=0.01)
    assert planar_winding(circle()[::-1]) == pytest.approx(1.0, rel=0.01)  # oriented normal
    assert planar_winding(torus_knot(2, 3, 90)) == pytest.approx(2.0, abs=0.1)
    assert planar_winding(torus_knot(3, 2, 90)) == pytest.approx(3.0, abs=0.2)
    # a figure-eight curve: its two lobes circulate in opposite senses
    t = 2 * np.pi * np.arange(60) / 60
    eight = np.stack([np.sin(t), np.sin(t) * np.cos(t), 0.01 * np.cos(t)], axis=1)
    assert abs(planar_winding(eight)) < 0.1


def test_tilt_analysis_counts_flips_only_while_toroidal():
    angles = np.concatenate([np.linspace(0, 180, 40), np.linspace(180, 0, 40)])
    frames = np.array([torus_knot(2, 3, 60) @ rotation_x(a).T for a in angles])
    times = 0.5 * np.arange(len(frames))
    result = tilt_analysis(frames, times)
    assert result.flips.count == 2
    assert result.toroidal.all() and np.all(result.winding > 1.8)
    np.testing.assert_allclose(result.tilt, angles, atol=1.0)
    np.testing.assert_allclose(result.inclination, np.minimum(angles, 180 - angles), atol=1.0)
    summary = result.to_dict()
    assert summary["flips"]["count"] == 2 and summary["fraction_toroidal"] == 1.0
    # frames that lost their circulation (here: squashed onto a line) do not count
    squashed = frames.copy()
    squashed[30:50, :, 1:] *= 1e-3
    result = tilt_analysis(squashed, times)
    assert not result.toroidal[30:50].any()
    assert result.flips.count <= 2
    with pytest.raises(ValueError, match="trajectory"):
        tilt_analysis(frames[0])
