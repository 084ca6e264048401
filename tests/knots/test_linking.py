"""Linking numbers and link templates against independent references: Gauss's integral by a
naive midpoint quadrature, the linking matrices of LinkInfo, the closed form of torus links."""

from __future__ import annotations

import math

import numpy as np
import pytest
import reference_model as rm

from knotmm.errors import TemplateError
from knotmm.knots.linking import gauss_linking_integral, linking_number, linking_numbers
from knotmm.shapes.links import braid_link, named_link, torus_link


def ring(n, radius=1.0, centre=(0, 0, 0), plane="xy"):
    t = 2 * np.pi * np.arange(n) / n
    c, s = radius * np.cos(t), radius * np.sin(t)
    z = np.zeros(n)
    x = {"xy": np.c_[c, s, z], "xz": np.c_[c, z, s]}[plane]
    return x + np.asarray(centre, float)


def test_two_round_rings_through_each_other_link_once_and_apart_not():
    a = ring(48)
    b = ring(48, centre=(1.0, 0, 0), plane="xz")
    far = ring(48, centre=(5.0, 0, 0), plane="xz")
    assert abs(gauss_linking_integral(a, b)) == pytest.approx(1.0, abs=1e-9)
    assert gauss_linking_integral(a, b) == pytest.approx(rm.gauss_linking(a, b), abs=0.02)
    assert linking_number(a, far) == 0
    # reversing one ring's direction flips the sign; swapping the rings does not
    assert linking_number(a, b[::-1]) == -linking_number(a, b)
    assert linking_number(b, a) == linking_number(a, b)


@pytest.mark.parametrize(("p", "q", "beads"), [(2, 2, 40), (2, 4, 60), (2, 6, 80), (3, 3, 90),
                                                (4, 2, 80), (6, 4, 120), (6, 3, 120)])
def test_torus_links_link_each_pair_pq_over_g_squared(p, q, beads):
    g = math.gcd(p, q)
    shape = torus_link(p, q, beads)
    assert len(shape.components) == g and shape.n_beads == beads
    for x in shape.components:  # every bond of every component is the bond length
        bonds = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
        np.testing.assert_allclose(bonds, 0.6, rtol=1e-6)
    want = (p // g) * (q // g)
    assert set(linking_numbers(shape.components).values()) == {want}
    mirrored = torus_link(p, q, beads, mirror=True)
    assert set(linking_numbers(mirrored.components).values()) == {-want}
    a, b = shape.components[:2]
    assert rm.gauss_linking(a, b) == pytest.approx(want, abs=0.05)


def _linkinfo_rows():
    dki = pytest.importorskip("database_knotinfo")
    rows = [r for r in dki.link_list(True)[1:] if r.get("braid_notation")
            and str(r.get("crossing_number")) in ("2", "4", "5", "6")]
    return rows


def _matrix(text):
    numbers = [int(v) for v in str(text).replace("{", " ").replace("}", " ").replace(",", " ")
               .split()]
    n = int(round(math.sqrt(len(numbers))))
    return np.array(numbers).reshape(n, n)


def test_linking_numbers_of_linkinfo_links_are_their_linking_matrices():
    """Every LinkInfo link of 2-6 crossings that builds at 200 beads: the Gauss integral of
    the template gives LinkInfo's pairwise linking numbers (as a multiset: components may
    come in another order)."""
    checked = 0
    for row in _linkinfo_rows():
        try:
            shape = named_link(row["name"], 200)
        except TemplateError:
            continue  # too tight at this size
        m = _matrix(row["linking_matrix"])
        want = sorted(int(m[i, j]) for i in range(len(m)) for j in range(i + 1, len(m)))
        got = sorted(linking_numbers(shape.components).values())
        assert got == want, row["name"]
        checked += 1
    assert checked >= 20


def test_common_links_and_refusals():
    assert linking_numbers(named_link("hopf", 40).components) == {(0, 1): 1}
    assert linking_numbers(named_link("solomon", 60).components) == {(0, 1): 2}
    assert linking_numbers(named_link("whitehead", 120).components) == {(0, 1): 0}
    borromean = named_link("borromean", 120)
    assert len(borromean.components) == 3
    assert set(linking_numbers(borromean.components).values()) == {0}
    with pytest.raises(TemplateError, match="60 or 62"):
        torus_link(2, 4, 61)
    with pytest.raises(TemplateError, match="a knot, not a link"):
        torus_link(2, 3, 60)
    with pytest.raises(TemplateError, match="a knot, not a link"):
        braid_link([1, 1, 1], 60)
    with pytest.raises(TemplateError, match="too few"):
        named_link("hopf", 10)
    with pytest.raises(TemplateError, match="not a link name"):
        named_link("hopff", 60)
