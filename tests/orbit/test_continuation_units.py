"""Continuation helpers: argument parsing, resampling, bifurcation detection."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from knotmm.errors import ConfigError
from knotmm.orbit.continuation import (
    ContinuationPoint,
    find_bifurcations,
    parse_range,
    resample_ring,
)


def test_parse_range():
    assert parse_range("model.bending_stiffness=5:500") == ("model.bending_stiffness", 5.0,
                                                            500.0)
    assert parse_range("knot.beads=60:40") == ("knot.beads", 60.0, 40.0)


@pytest.mark.parametrize("bad", ["model.bending_stiffness", "model.bending_stiffness=5",
                                 "model.bending_stiffness=a:b", "run.duration=1:2",
                                 "model.bond_stiffness=3:3"])
def test_parse_range_rejects_with_the_argument_named(bad):
    with pytest.raises(ConfigError, match="--continue"):
        parse_range(bad)


def test_resample_ring_of_a_circle_is_a_stretched_circle():
    n, radius = 30, 2.0
    phi = 2 * np.pi * np.arange(n) / n
    x = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros(n)])
    y = resample_ring(x, 45)
    assert y.shape == (45, 3)
    r = np.hypot(y[:, 0], y[:, 1])
    # chords: the polygon's vertices keep the radius; the points between them lie inside
    # by at most radius (1 - cos(pi / n)), all stretched by 45 / 30
    assert r.max() == pytest.approx(radius * 1.5, rel=1e-12)
    assert r.min() >= radius * 1.5 * math.cos(math.pi / n) - 1e-12
    bonds = np.linalg.norm(np.roll(y, -1, axis=0) - y, axis=1)
    assert np.ptp(bonds) < 0.02 * bonds.mean()


def _point(value, multipliers):
    mult = np.array(multipliers, dtype=complex)
    fl = SimpleNamespace(multipliers=mult, n_unstable=int(np.sum(np.abs(mult) > 1)))
    return ContinuationPoint(value, orbit=None, floquet=fl)


def test_bifurcation_kinds_and_interpolated_location():
    branch = [_point(0.0, [0.8, 0.1]), _point(1.0, [1.2, 0.1])]
    (b,) = find_bifurcations(branch)
    assert "fold or pitchfork" in b.kind
    assert b.value == pytest.approx(0.5)  # |mu| - 1 goes -0.2 -> 0.2
    branch = [_point(0.0, [-0.9]), _point(2.0, [-1.3])]
    (b,) = find_bifurcations(branch)
    assert "period doubling" in b.kind
    assert b.value == pytest.approx(2.0 * 0.1 / 0.4)
    z = 1.1 * np.exp(0.4j)
    branch = [_point(0.0, [0.95 * np.exp(0.4j), 0.95 * np.exp(-0.4j)]),
              _point(1.0, [z, np.conj(z)])]
    (b,) = find_bifurcations(branch)
    assert "Neimark-Sacker" in b.kind
    assert "0.4" in b.kind
    assert find_bifurcations([_point(0.0, [0.5]), _point(1.0, [0.9])]) == []


def test_discrete_parameter_reports_a_change_without_a_crossing_point():
    branch = [_point(44.0, [1.03 * np.exp(0.4j)]), _point(45.0, [0.95 * np.exp(0.08j)])]
    (b,) = find_bifurcations(branch, discrete=True)
    assert b.value == 45.0 and "discrete" in b.kind and "Neimark" not in b.kind
    assert "gains stability" in b.notes[0]


@pytest.mark.parametrize("key", ["model.bending_stiffness", "model.bond_stiffness",
                                 "model.gravity", "model.lj_epsilon", "model.lj_sigma",
                                 "model.bond_length", "knot.beads"])
def test_a_point_s_model_is_the_run_s_with_the_key_replaced(key):
    """Each point's model comes from the run plan's (its ``ChainModel`` with the followed
    field replaced, issue 31): the model of the run file with that key replaced."""
    from knotmm.config import RunConfig
    from knotmm.model.parameters import ChainModel
    from knotmm.orbit.continuation import CONTINUOUS_KEYS, DISCRETE_KEYS, _model
    from knotmm.plan import PlanParts

    assert key in CONTINUOUS_KEYS + DISCRETE_KEYS
    cfg = RunConfig.from_dict({"model": {"bending_stiffness": 7.5, "gravity": 0.5,
                                         "segment_repulsion": True}})
    value = 48 if key == "knot.beads" else np.float64(0.4375)  # as the Newton solve gives it
    point = _model(PlanParts.of(cfg).model, key, value)
    assert point == ChainModel.from_config(cfg.replace({key: value}))
