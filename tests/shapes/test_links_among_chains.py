"""A link among other ``[[chains]]`` as run.toml records it, and the system's template line
once its chains' knot types are found (issue 34).

* run.toml's ``links`` name a link's chains by the system's ids (``B``, ``C`` after a knot
  ``A``), with their linking numbers keyed by them and equal to a naive Gauss sum written
  here;
* the system's ``template`` line carries the knot types identified after the start (a
  link's components are identified beside the run, as a knot's are).
"""

from __future__ import annotations

import numpy as np
import pytest
from reference_model import gauss_linking  # a naive sum, not knotmm's

from knotmm.config import RunConfig
from knotmm.knots.identify import topoly_available
from knotmm.shapes.builder import build_template
from knotmm.shapes.template import Template

TREFOIL_THEN_HOPF = {"chains": [
    {"kind": "torus", "p": 2, "q": 3, "beads": 60, "offset": [9.0, 0.0, 0.0]},
    {"kind": "knotinfo", "name": "hopf", "beads": 60, "offset": [-6.0, 0.0, 0.0]},
]}




def test_a_link_after_a_knot_is_recorded_by_the_systems_chain_names():
    system = build_template(RunConfig.from_dict(TREFOIL_THEN_HOPF), identify="skip")
    assert system.layout.lengths == (60, 30, 30)
    [link] = system.facts["links"]
    assert link["chains"] == ["B", "C"]
    assert list(link["linking_numbers"]) == ["B-C"]
    b, c = (system.positions[sl] for sl in system.layout.slices()[1:])
    assert link["linking_numbers"]["B-C"] == round(gauss_linking(b, c))
    assert abs(gauss_linking(b, c)) == pytest.approx(1.0, abs=0.02)


@pytest.mark.skipif(not topoly_available(), reason="topoly (knot identification) missing")
def test_the_system_template_line_carries_knot_types_found_after_the_start():
    system = build_template(RunConfig.from_dict(TREFOIL_THEN_HOPF), identify="later")
    before = system.description
    assert "B component 0;" in before + ";" and "0_1" not in before
    system.settle_knot_type(wait=True)
    assert system.description == (
        "3 chains: A T(2,3), +3_1; B component 0, 0_1; C component 1, 0_1"), system.description
    assert system.facts["template"] == system.description
    assert [c.get("template_knot_type") for c in system.facts["chains"]] == [
        "+3_1", "0_1", "0_1"]


def test_the_system_line_takes_each_chains_new_description_in_its_place():
    """A prefix (a link's name) and chain names that end another's are left alone."""
    parts = [Template(np.zeros((3, 3)), d, {}, 0.0, None) for d in ("component 1", "ring")]
    system = Template(np.zeros((6, 3)), "hopf, 2 chains: A component 1; B ring", {}, 0.0, None,
                      parts=parts)
    system.layout = type(system.layout)((3, 3))
    parts[0].description, parts[1].description = "component 1, 0_1", "ring, +3_1"
    system._describe_parts(["component 1", "ring"])
    assert system.description == "hopf, 2 chains: A component 1, 0_1; B ring, +3_1"
