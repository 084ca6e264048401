"""The analysis of several chains against trajectories with known answers: rigid rings
falling at given speeds, at a given distance and angle, linked or not."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.analysis.chains import axis_angles, centre_distances
from knotmm.analysis.core import analyze
from knotmm.io.run_data import RunData


def ring(n, radius, tilt_deg=0.0):
    t = 2 * np.pi * np.arange(n) / n
    x = np.c_[radius * np.cos(t), radius * np.sin(t), np.zeros(n)]
    a = np.radians(tilt_deg)  # turned about x
    rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return x @ rot.T


def two_ring_run(n_frames=241, dt=0.25, speeds=(2.0, 3.0), gap=6.0, tilt=35.0, linked=False):
    a0 = ring(40, 3.0)
    b0 = ring(30, 2.0, tilt) + ([1.5, 0, 0] if linked else [gap, 0, 0])
    if linked:  # b in the xz plane through a's rim: a Hopf pair
        b0 = ring(30, 2.0, 90.0) + [3.0, 0, 0]
    times = np.arange(n_frames) * dt
    frames = []
    for t in times:
        frames.append(np.vstack([a0 - [0, 0, speeds[0] * t], b0 - [0, 0, speeds[1] * t]]))
    bonds = [(i, (i + 1) % 40) for i in range(40)] + [(40 + i, 40 + (i + 1) % 30)
                                                     for i in range(30)]
    config = {
        "chains": [{"kind": "torus", "p": 2, "q": 3, "beads": 40},
                   {"kind": "torus", "p": 2, "q": 3, "beads": 30}],
        "model": {"gravity": 1.0, "bond_length": 0.47},
        "knotmm": {"layout": {"lengths": [40, 30], "closed": [True, True]},
                   "chains": [{"id": "A", "beads": 40, "closed": True},
                              {"id": "B", "beads": 30, "closed": True}]},
    }
    return RunData.from_arrays(np.array(frames), dt, config=config, bonds=bonds)


def test_distances_and_axis_angles_have_their_closed_forms():
    data = two_ring_run()
    a, b = slice(0, 40), slice(40, 70)
    d = centre_distances(data.positions, a, b)
    # centres: (0, 0, -2t) and (6, 0, -3t): distance sqrt(36 + t^2)
    np.testing.assert_allclose(d, np.sqrt(36 + data.times**2), rtol=1e-12)
    np.testing.assert_allclose(axis_angles(data.positions, a, b), 35.0, atol=1e-9)


def test_each_chain_gets_its_own_speed_and_the_system_its_centre_of_mass_speed():
    data = two_ring_run()
    result = analyze(data, knot_samples=0)
    d = result.to_dict()
    chains = d["chains"]
    assert [c["id"] for c in chains] == ["A", "B"] and [c["beads"] for c in chains] == [40, 30]
    assert chains[0]["sedimentation_velocity"] == pytest.approx(2.0, rel=1e-9)
    assert chains[1]["sedimentation_velocity"] == pytest.approx(3.0, rel=1e-9)
    # the centre of mass of all 70 beads falls at (40 * 2 + 30 * 3) / 70
    assert d["sedimentation_velocity"] == pytest.approx(170 / 70, rel=1e-9)
    pair = d["system"]["pairs"][0]
    assert pair["chains"] == "A-B" and pair["distance_start"] == pytest.approx(6.0)
    assert pair["axis_angle_start_deg"] == pytest.approx(35.0)
    assert d["system"]["linking_numbers"] == {"A-B": 0}
    # separate chains are no one structure: the system's swirl is n/a, with the reason
    assert d["tau_swirl"] is None and d["swirl_detected"] is None
    assert "separate chains" in d["not_applicable"]["tau_swirl"]
    assert "chain B" in result.summary() and "linking numbers" in result.summary()


def test_a_linked_pair_is_linked_throughout():
    data = two_ring_run(speeds=(2.0, 2.0), linked=True)
    d = analyze(data, knot_samples=0).to_dict()
    assert abs(d["system"]["linking_numbers"]["A-B"]) == 1
    assert d["system"]["linking_numbers_end"] == d["system"]["linking_numbers"]
    assert d["system"]["linking_number_changes"] == []
