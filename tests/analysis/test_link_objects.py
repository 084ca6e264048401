"""Links among other chains, and links the linking number cannot see (issue 34).

* a torus link T(2,4) beside a separate trefoil, in one ``[[chains]]`` system: the link is
  found (from run.toml's record, or from its linking number alone) and analysed as one
  object, equal to its beads analysed alone; the trefoil's row equals its beads alone;
* the Whitehead link (linking number 0), built here as the closure of the 3-braid
  s1 s2^-1 s1 s2^-2 and read back from a DCD/PDB pair without run.toml: without knot
  identification its rings are "not determined", never "not linked" (a plane does not
  separate them), with the reason; with it, topoly's HOMFLY-PT polynomial of the pair (L5a1,
  not a split link's) makes them linked; two rings far apart are "not linked" (a plane
  separates them); two unlinked concentric rings in one plane are "not determined" (no
  proof either way);
* :func:`knotmm.analysis.linkage.separated_by_plane` against configurations whose answer is
  known.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference_model import gauss_linking  # a naive sum, not knotmm's
from same_values import assert_same_values
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis.core import analyze, analyze_run
from knotmm.analysis.linkage import (
    LINKED,
    NOT_DETERMINED,
    NOT_LINKED,
    entry_chains,
    separated_by_plane,
)
from knotmm.io.run_data import RunData
from knotmm.knots.identify import topoly_available
from knotmm.model.layout import ChainLayout

DT = 0.5
TIMES = np.arange(301) * DT
MODEL = {"gravity": 1.0, "bond_length": 0.6, "bending_stiffness": 5.0}
M = 40  # beads per ring of the torus link
LINK_ENTRY = {"kind": "torus", "p": 2, "q": 4, "beads": 2 * M}
TREFOIL_ENTRY = {"kind": "torus", "p": 2, "q": 3, "beads": 60}


def link_and_trefoil(record: bool = True) -> RunData:
    """Chain A: a trefoil swirling on its own (60 beads, 16 d to the side); chains B, C: the
    torus link T(2,4) swirling as one torus (two T(1,2) rings, swirl phases pi apart)."""
    trefoil = vortex_knot_positions(TIMES, n_beads=60, rho0=3.0, velocity=2.6, tau_swirl=7.0,
                                    tau_rot=250.0) + [16.0, 0.0, 0.0]
    kw = dict(n_beads=M, p=1, q=2, rho0=4.0, swirl_amplitude=0.6, velocity=2.0,
              tau_swirl=10.0, tau_rot=150.0)
    x = np.concatenate([trefoil, vortex_knot_positions(TIMES, **kw),
                        vortex_knot_positions(TIMES, phase=np.pi, **kw)], axis=1)
    layout = ChainLayout((60, M, M), (True, True, True))
    facts = {"layout": layout.to_record(),
             "chains": [{"id": c, "beads": n, "closed": True}
                        for c, n in zip(layout.ids, layout.lengths, strict=True)]}
    if record:  # as run.toml wrote it before the ids were the system's: the part's own
        facts["links"] = [{"link": "T(2,4)", "linking_numbers": {"A-B": 2}}]
    config = {"chains": [dict(TREFOIL_ENTRY, offset=[16.0, 0.0, 0.0]), dict(LINK_ENTRY)],
              "model": dict(MODEL), "knotmm": facts}
    return RunData.from_arrays(x, DT, config=config, bonds=layout.bonds())


_same = assert_same_values


@pytest.mark.parametrize("record", [True, False], ids=["run.toml's record", "linking number"])
def test_a_link_among_other_chains_is_one_object_equal_to_its_beads_alone(record):
    data = link_and_trefoil(record)
    result = analyze(data, knot_samples=0)
    d = result.to_dict()
    system = d["system"]
    assert system["kind"] == "links and separate chains"
    assert system["linking_numbers"] == {"A-B": 0, "A-C": 0, "B-C": 2}
    assert system["linked"]["B-C"]["status"] == LINKED
    assert system["linked"]["A-B"]["status"] == NOT_LINKED  # 16 d apart: a plane between
    [link] = system["links"]
    assert link["chains"] == ["B", "C"]
    # the link's beads alone, as a run of that link
    layout = ChainLayout((M, M), (True, True))
    alone = RunData.from_arrays(
        data.positions[:, 60:], DT,
        config={"knot": dict(LINK_ENTRY), "model": dict(MODEL),
                "knotmm": {"link": "T(2,4)", "layout": layout.to_record()}},
        bonds=layout.bonds())
    own = analyze(alone, knot_samples=0).to_dict()
    for key, value in link.items():
        if key not in ("chains", "link", "notes"):
            _same(own[key], value, f"link: {key}")
    # and what it is: the torus link swirling at its known period, the torus formulas on
    assert (link["p"], link["q"]) == (2, 4)
    assert link["tau_swirl"] == pytest.approx(10.0, rel=1e-3)
    assert link["major_radius"] == pytest.approx(4.0, rel=1e-3)
    assert link["sedimentation_velocity"] == pytest.approx(2.0, rel=1e-6)
    # the trefoil: its own row equals its beads alone
    trefoil = RunData.from_arrays(
        data.positions[:, :60], DT, config={"knot": dict(TREFOIL_ENTRY, closed=True),
                                            "model": dict(MODEL)},
        bonds=ChainLayout((60,), (True,)).bonds())
    mine = analyze(trefoil, knot_samples=0).to_dict()
    row = d["chains"][0]
    for key in row:
        if key not in ("id", "beads", "closed", "notes"):
            _same(mine[key], row[key], f"chain A: {key}")
    assert row["tau_swirl"] == pytest.approx(7.0, rel=1e-3)
    # the system as a whole has no one structure; the table names the link
    assert d["major_radius"] is None and "links and separate chains" in (
        d["not_applicable"]["major_radius"])
    assert "link B-C" in result.summary()


def test_a_link_component_row_takes_no_link_name_as_its_knot():
    """Each ring of a [[chains]] link is a component, not the link (no T(2,4) formulas for
    one ring of it)."""
    d = analyze(link_and_trefoil(), knot_samples=0).to_dict()
    for row in d["chains"][1:]:
        assert row["p"] is None and row["torus_knot"] is not True


def braid_closure(word, n_strands=3, per_generator=8, radius=6.0, width=1.2, lift=0.6):
    """The closed braid of ``word`` (+i: strand in slot i over slot i + 1, -i: under) about
    the z axis, strand slot k at radius ``radius + k width``: one ring per cycle of the
    braid's permutation, beads in order, shape (n, 3) each."""
    slots = list(range(n_strands))
    paths = {s: [] for s in range(n_strands)}
    for g, gen in enumerate(word):
        i = abs(gen) - 1
        for step in range(per_generator):
            f = step / per_generator
            theta = 2 * np.pi * (g + f) / len(word)
            for s in range(n_strands):
                k, z = slots[s], 0.0
                r = radius + k * width
                if k in (i, i + 1):
                    move = 1 if k == i else -1
                    r = radius + (k + move * (1 - np.cos(np.pi * f)) / 2) * width
                    z = (lift if (k == i) == (gen > 0) else -lift) * np.sin(np.pi * f)
                paths[s].append((r * np.cos(theta), r * np.sin(theta), z))
        slots = [i + 1 if k == i else i if k == i + 1 else k for k in slots]
    rings, seen = [], set()
    for first in range(n_strands):
        ring, s = [], first
        while s not in seen:
            seen.add(s)
            ring += paths[s]
            s = slots[s]
        if ring:
            rings.append(np.array(ring))
    return rings




def _falling(rings, n_frames=40, speed=1.5):
    x0 = np.concatenate(rings)
    return np.stack([x0 - [0.0, 0.0, speed * t * DT] for t in range(n_frames)])


def test_the_whitehead_link_from_a_file_is_not_determined_never_unlinked(tmp_path):
    rings = braid_closure([1, -2, 1, -2, -2])  # the Whitehead link L5a1 (5 crossings)
    assert len(rings) == 2
    assert abs(gauss_linking(*rings)) < 0.05  # linking number 0
    layout = ChainLayout(tuple(len(r) for r in rings), (True, True))
    directory = write_run_directory(tmp_path / "wh", _falling(rings), DT,
                                    write_run_file=False, layout=layout)
    result = analyze_run(directory / "trajectory.dcd", topology=directory / "topology.pdb",
                         frame_interval=DT, plots=False, knot_samples=0)
    d = result.to_dict()
    assert [c["beads"] for c in d["chains"]] == [80, 40]
    assert d["system"]["linking_numbers"] == {"A-B": 0}
    status = d["system"]["linked"]["A-B"]
    assert status["status"] == NOT_DETERMINED and "linking number 0" in status["reason"]
    assert "not determined" in d["system"]["kind"]
    assert d["major_radius"] is None and "not determined" in d["not_applicable"]["major_radius"]
    assert any("A-B: linked or not is not determined" in n for n in d["notes"])
    assert "not determined" in result.summary()


@pytest.mark.skipif(not topoly_available(), reason="topoly (knot identification) missing")
def test_the_whitehead_link_is_linked_by_its_polynomial_where_identification_is_on(tmp_path):
    """With knot identification on, the pair's HOMFLY-PT polynomial (topoly) is L5a1's, not a
    split link's: linked, and the system is one link; unlinked concentric rings (a split
    link's polynomial) stay not determined."""
    rings = braid_closure([1, -2, 1, -2, -2])
    layout = ChainLayout(tuple(len(r) for r in rings), (True, True))
    directory = write_run_directory(tmp_path / "wh", _falling(rings), DT,
                                    write_run_file=False, layout=layout)
    d = analyze_run(directory / "trajectory.dcd", topology=directory / "topology.pdb",
                    frame_interval=DT, plots=False, knot_samples=2).to_dict()
    status = d["system"]["linked"]["A-B"]
    assert status["status"] == LINKED and "L5a1" in status["reason"], status
    assert d["system"]["kind"] == "link"
    t = 2 * np.pi * np.arange(30) / 30
    circle = np.c_[np.cos(t), np.sin(t), 0 * t]
    concentric = RunData.from_arrays(
        _falling([2 * circle, 4 * circle], n_frames=20), DT, config={"model": dict(MODEL)},
        bonds=ChainLayout((30, 30), (True, True)).bonds())
    status = analyze(concentric, knot_samples=2).to_dict()["system"]["linked"]["A-B"]
    assert status["status"] == NOT_DETERMINED and "split link" in status["reason"], status


def test_rings_a_plane_separates_are_not_linked_and_interleaved_ones_not_determined():
    t = 2 * np.pi * np.arange(30) / 30
    circle = np.c_[np.cos(t), np.sin(t), 0 * t]
    for rings, expected in (
        ([3 * circle, 3 * circle + [10.0, 0.0, 0.0]], NOT_LINKED),   # side by side
        ([3 * circle, 3 * circle + [0.0, 0.0, 4.0]], NOT_LINKED),    # one above the other
        ([2 * circle, 4 * circle], NOT_DETERMINED),                  # concentric, one plane
    ):
        layout = ChainLayout((30, 30), (True, True))
        data = RunData.from_arrays(_falling(rings, n_frames=20), DT,
                                   config={"model": dict(MODEL)}, bonds=layout.bonds())
        d = analyze(data, knot_samples=0).to_dict()
        assert d["system"]["linked"]["A-B"]["status"] == expected, rings
        kind = d["system"]["kind"]
        assert kind == ("separate chains" if expected == NOT_LINKED
                        else "chains whose linking is not determined")


def test_separated_by_plane_against_known_configurations():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(50, 3))
    assert separated_by_plane(a, a + [10.0, 0.0, 0.0])
    assert separated_by_plane(a, a + [0.0, 0.0, -9.0])
    assert not separated_by_plane(a, a + [0.1, 0.0, 0.0])
    # a point inside the other set's hull is never separated
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    assert not separated_by_plane(cube, np.array([[0.5, 0.5, 0.5], [5.0, 5.0, 5.0]]))
    # a diagonal separation no coordinate axis shows: two sheets x + y = 0 and x + y = 1.2
    u = rng.uniform(-3, 3, size=(40, 2))
    sheet = np.c_[u[:, 0], -u[:, 0], u[:, 1]]
    other = sheet + [0.6, 0.6, 0.0]
    for k in range(3):  # their projections on x, y and z overlap
        assert sheet[:, k].max() > other[:, k].min() and other[:, k].max() > sheet[:, k].min()
    assert separated_by_plane(sheet, other)


def test_entry_chains_follow_the_entries_bead_counts():
    entries = [{"beads": 60}, {"beads": 80}, {"beads": 20}]
    assert entry_chains(entries, [60, 40, 40, 20]) == [[0], [1, 2], [3]]
    assert entry_chains(entries, [60, 50, 40, 20]) is None
    assert entry_chains([{"kind": "torus"}], [60]) is None
