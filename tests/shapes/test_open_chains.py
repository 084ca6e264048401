"""Open filaments and systems of chains: shapes against their closed forms, the templates a
run file builds, overlaps refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.errors import TemplateError
from knotmm.knots.writhe import writhe
from knotmm.shapes.builder import build_template
from knotmm.shapes.open_chains import arc, helix, straight


def bonds(x):
    return np.linalg.norm(np.diff(x, axis=0), axis=1)


def test_straight_arc_and_helix_have_exact_bonds_and_their_closed_form_shapes():
    x = straight(10, 0.6)
    np.testing.assert_allclose(bonds(x), 0.6, rtol=1e-12)
    assert np.linalg.norm(x[-1] - x[0]) == pytest.approx(5.4)
    y = arc(13, 0.6, 180.0)
    np.testing.assert_allclose(bonds(y), 0.6, rtol=1e-12)
    # a half circle: end-to-end distance is its diameter, 2 R with R = l / (2 sin(pi / 24))
    radius = 0.6 / (2 * math.sin(math.pi / 24))
    assert np.linalg.norm(y[-1] - y[0]) == pytest.approx(2 * radius, rel=1e-12)
    h = helix(40, 0.6, radius=2.0, pitch=3.0)
    np.testing.assert_allclose(bonds(h), 0.6, rtol=1e-9)
    # the axis: the circle through the beads' (x, y) (an algebraic least-squares fit)
    a = np.c_[2 * h[:, 0], 2 * h[:, 1], np.ones(len(h))]
    cx, cy, k = np.linalg.lstsq(a, h[:, 0] ** 2 + h[:, 1] ** 2, rcond=None)[0]
    radius = math.sqrt(k + cx**2 + cy**2)
    assert radius == pytest.approx(2.0, rel=1e-9)
    phi = np.unwrap(np.arctan2(h[:, 1] - cy, h[:, 0] - cx))
    slope = np.polyfit(phi, h[:, 2], 1)[0]  # rise per radian: pitch / (2 pi)
    assert slope == pytest.approx(3.0 / (2 * math.pi), rel=1e-9)
    assert writhe(h, closed=False) > 0  # right-handed for pitch > 0


def _template(knot, **tables):
    return build_template(RunConfig.from_dict({"knot": knot, **tables}), identify="skip")


@pytest.mark.parametrize("kind", ["straight", "arc", "helix"])
def test_open_kinds_build_one_open_chain(kind):
    tpl = _template({"kind": kind, "beads": 30})
    assert tpl.layout.n_chains == 1 and tpl.layout.closed == (False,)
    assert len(tpl.layout.bonds()) == 29
    np.testing.assert_allclose(bonds(tpl.positions), 0.6, rtol=1e-9)


def test_a_torus_knot_cut_open_keeps_its_beads_without_the_closing_bond():
    closed = _template({"p": 2, "q": 3, "beads": 60})
    cut = _template({"p": 2, "q": 3, "beads": 60, "closed": False})
    np.testing.assert_allclose(cut.positions, closed.positions)
    assert cut.layout.closed == (False,) and len(cut.layout.bonds()) == 59


def test_chains_that_overlap_are_refused_with_the_distance_to_move_them():
    with pytest.raises(TemplateError, match=r"chains\[0\] and chains\[1\] overlap") as info:
        build_template(RunConfig.from_dict({"chains": [
            {"beads": 60, "offset": [0, 0, 0]}, {"beads": 60, "offset": [1.0, 0, 0]}]}),
            identify="skip")
    assert "apart" in str(info.value)
    ok = build_template(RunConfig.from_dict({"chains": [
        {"beads": 60, "offset": [-6.0, 0, 0]}, {"beads": 60, "offset": [6.0, 0, 0]}]}),
        identify="skip")
    assert ok.layout.lengths == (60, 60)
    centres = [ok.positions[sl].mean(axis=0) for sl in ok.layout.slices()]
    np.testing.assert_allclose(centres, [[-6, 0, 0], [6, 0, 0]], atol=1e-12)


def test_a_rotation_turns_a_chain_about_its_centre():
    base = _template({"p": 2, "q": 3, "beads": 60}).positions
    tpl = build_template(RunConfig.from_dict({"chains": [
        {"beads": 60, "rotation": [1, 0, 0, 90], "offset": [0, 0, 0]}]}), identify="skip")
    # 90 degrees about x: (x, y, z) -> (x, -z, y)
    want = np.c_[base[:, 0], -base[:, 2], base[:, 1]]
    np.testing.assert_allclose(tpl.positions - tpl.positions.mean(axis=0),
                               want - want.mean(axis=0), atol=1e-12)
