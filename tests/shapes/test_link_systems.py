"""Links and systems built as the run file says (issue 30, BUG-10, BUG-11, BUG-22).

A link's ``knot.perturbation``, ``knot.seed`` and ``knot.major_radius`` act as they do on a
single knot; ``closed = false`` cuts each component open on its own; the overlap message's
advised distance is one at which the chains pass the check.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.errors import TemplateError
from knotmm.shapes.builder import build_template


def _link(**knot):
    knot = {"kind": "knotinfo", "name": "hopf", "beads": 60, **knot}
    return build_template(RunConfig.from_dict({"knot": knot}), identify="skip")


def _radii(x: np.ndarray) -> np.ndarray:
    """Distance of each bead from the vertical axis through the centre, in d."""
    centred = x - x.mean(axis=0)
    return np.hypot(centred[:, 0], centred[:, 1])


# -- BUG-10 -------------------------------------------------------------------------------
def test_a_perturbed_link_moves_its_beads_by_its_seed():
    plain = _link()
    one = _link(perturbation=0.05, seed=1)
    again = _link(perturbation=0.05, seed=1)
    other = _link(perturbation=0.05, seed=2)
    by_run_seed = build_template(RunConfig.from_dict({
        "knot": {"kind": "knotinfo", "name": "hopf", "beads": 60, "perturbation": 0.05},
        "run": {"seed": 2}}), identify="skip")
    shift = one.positions - plain.positions
    assert 0.02 < shift.std() < 0.08  # about the perturbation's std per coordinate
    np.testing.assert_array_equal(one.positions, again.positions)
    assert np.abs(one.positions - other.positions).max() > 0.01
    np.testing.assert_array_equal(by_run_seed.positions, other.positions)  # seed = run.seed
    assert one.resolved["knot.seed"] == 1 and by_run_seed.resolved["knot.seed"] == 2
    assert any("perturbed by 0.05" in note for note in one.notes)
    assert one.layout == plain.layout
    assert one.chain_facts["linking_numbers"] == {"A-B": 1}


@pytest.mark.parametrize("knot", [
    {"kind": "knotinfo", "name": "hopf", "beads": 60},
    {"kind": "torus", "p": 2, "q": 4, "beads": 80},
    {"kind": "knotinfo", "name": "whitehead", "beads": 90},
])
def test_a_link_major_radius_sets_its_torus(knot):
    plain = build_template(RunConfig.from_dict({"knot": knot}), identify="skip")
    wide = build_template(RunConfig.from_dict({"knot": {**knot, "major_radius": 6.0}}),
                          identify="skip")
    # the beads lie on the tube about the circle of the given radius
    assert _radii(wide.positions).mean() == pytest.approx(6.0, abs=1.5)
    assert _radii(wide.positions).mean() > _radii(plain.positions).mean() + 1.0
    assert wide.layout.n_beads == plain.layout.n_beads
    assert wide.layout.n_chains == plain.layout.n_chains
    assert any("knot.major_radius=6" in note and "relax" in note for note in wide.notes)


def test_a_link_major_radius_too_small_or_too_large_is_refused_in_one_line():
    with pytest.raises(TemplateError, match=r"knot\.major_radius=1e-300 is too small") as info:
        _link(major_radius=1e-300)
    assert "\n" not in str(info.value)
    with pytest.raises(TemplateError, match=r"knot\.major_radius=30 is too large: .*"
                                            r"run\.max_bond_length=3"):
        _link(major_radius=30.0)
    with pytest.raises(TemplateError, match=r"knot\.major_radius=10000 ") as info:
        _link(major_radius=1e4)
    assert "\n" not in str(info.value)


def test_a_link_perturbation_too_large_is_refused_naming_it():
    for huge in (1e5, 50.0):
        with pytest.raises(TemplateError, match=r"knot\.perturbation=.* is too large") as info:
            _link(perturbation=huge)
        assert "\n" not in str(info.value)


# -- BUG-11 -------------------------------------------------------------------------------
def test_a_link_cut_open_is_one_open_chain_per_component():
    ring = _link()
    cut = _link(closed=False)
    assert cut.layout.lengths == (30, 30) and cut.layout.closed == (False, False)
    np.testing.assert_allclose(cut.positions, ring.positions)
    bonds = {tuple(b) for b in cut.layout.bonds().tolist()}
    assert (29, 30) not in bonds and (0, 29) not in bonds and len(bonds) == 58
    assert [p.n_beads for p in cut.parts] == [30, 30]
    assert "linking_numbers" not in cut.chain_facts  # not defined for open chains
    assert "cut open" in cut.description


def test_a_link_cut_open_inside_chains_keeps_its_components_apart():
    tpl = build_template(RunConfig.from_dict({"chains": [
        {"kind": "knotinfo", "name": "hopf", "beads": 60, "closed": False,
         "offset": [-5.0, 0.0, 0.0]},
        {"kind": "straight", "beads": 10, "offset": [5.0, 0.0, 0.0]},
    ]}), identify="skip")
    assert tpl.layout.lengths == (30, 30, 10)
    assert tpl.layout.closed == (False, False, False)


def test_a_perturbed_knot_cut_open_is_perturbed_once():
    ring = _link(kind="torus", p=2, q=3, beads=60, perturbation=0.05, seed=3)
    cut = _link(kind="torus", p=2, q=3, beads=60, perturbation=0.05, seed=3, closed=False)
    np.testing.assert_allclose(cut.positions, ring.positions, atol=1e-12)
    perturbed_link = _link(perturbation=0.05, seed=3)
    cut_link = _link(perturbation=0.05, seed=3, closed=False)
    np.testing.assert_allclose(cut_link.positions, perturbed_link.positions, atol=1e-12)


# -- BUG-22 -------------------------------------------------------------------------------
@pytest.mark.parametrize("half", [0.5, 0.88])
def test_the_advised_distance_of_two_overlapping_chains_passes(half):
    def chains(h):
        return RunConfig.from_dict({"chains": [
            {"kind": "torus", "beads": 30, "offset": [0.0, 0.0, h]},
            {"kind": "torus", "beads": 30, "offset": [0.0, 0.0, -h]}]})

    with pytest.raises(TemplateError, match="overlap") as info:
        build_template(chains(half), identify="skip")
    advised = float(re.search(r"at least (\S+) d apart", str(info.value)).group(1))
    assert advised > 2 * half
    tpl = build_template(chains(advised / 2), identify="skip")
    assert tpl.layout.lengths == (30, 30)
