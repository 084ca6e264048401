"""Shapes at extreme numbers (issue 30, BUG-18 and BUG-21): a rotation axis of any finite
size turns the chain, an axis without a direction is refused, and arcs and helices too large
for the trajectory files are refused with one line naming the key instead of overflowing."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.errors import ConfigError, TemplateError
from knotmm.shapes.assembly import place, rotation_matrix
from knotmm.shapes.open_chains import arc, helix


@pytest.mark.parametrize("scale", [1e200, 1e-300, 1e300])
def test_rotation_axis_of_any_finite_size_turns_the_chain(scale):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow or underflow on the way
        turned = rotation_matrix([scale, scale, 0.0, 90.0])
    np.testing.assert_allclose(turned, rotation_matrix([1.0, 1.0, 0.0, 90.0]), atol=1e-15)
    assert not np.allclose(turned, np.eye(3))


def test_a_huge_axis_rotates_a_placed_chain(trefoil40):
    moved = place(trefoil40, [1e200, 1e200, 0.0, 90.0], [0.0, 0.0, 0.0])
    expected = place(trefoil40, [1.0, 1.0, 0.0, 90.0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(moved, expected, atol=1e-12)
    assert not np.allclose(moved, place(trefoil40, None, [0.0, 0.0, 0.0]))


@pytest.mark.parametrize("axis", [[0.0, 0.0, 0.0], [1e-320, 0.0, 0.0], [np.inf, 0.0, 0.0]])
def test_an_axis_without_a_direction_is_refused(axis):
    with pytest.raises(TemplateError, match="no direction"):
        rotation_matrix([*axis, 90.0])


@pytest.mark.parametrize("rotation", [[1e-320, 0.0, 0.0, 90.0], [0.0, -4e-310, 0.0, 90.0]])
def test_a_run_file_names_the_rotation_without_a_direction(rotation):
    data = {"chains": [{"beads": 30, "rotation": rotation}]}
    with pytest.raises(ConfigError, match=r"chains\[0\]\.rotation = .*largest part"):
        RunConfig.from_dict(data)


def test_a_tiny_normal_axis_is_accepted():
    cfg = RunConfig.from_dict({"chains": [{"beads": 30, "rotation": [1e-300, 0.0, 0.0, 90.0]}]})
    np.testing.assert_allclose(rotation_matrix(cfg.chains[0]["rotation"]),
                               rotation_matrix([1.0, 0.0, 0.0, 90.0]))


def test_an_arc_too_flat_for_the_files_is_refused_with_the_smallest_angle():
    with pytest.raises(TemplateError, match=r"knot.arc_degrees=1e-300 .* use knot.arc_degrees "
                                            r">= 0.00654"):
        arc(20, 0.6, 1e-300)
    x = arc(20, 0.6, 0.00654)  # the angle the message advises works
    np.testing.assert_allclose(np.linalg.norm(np.diff(x, axis=0), axis=1), 0.6, rtol=1e-9)


@pytest.mark.parametrize(("radius", "pitch", "key"), [(1e300, 1e300, "helix_radius"),
                                                      (2.0, 1e300, "helix_pitch")])
def test_a_helix_past_the_largest_length_is_refused(radius, pitch, key):
    with pytest.raises(TemplateError, match=f"knot.{key}=1e\\+300: must be within 100000 d"):
        helix(40, 0.6, radius, pitch)


def test_a_helix_at_the_largest_length_keeps_its_bonds():
    x = helix(40, 0.6, 1e5, 1e5)
    np.testing.assert_allclose(np.linalg.norm(np.diff(x, axis=0), axis=1), 0.6, rtol=1e-9)
