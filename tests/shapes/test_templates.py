"""Tests of knot templates (knotmm.shapes) and the bead PDB writer."""

from __future__ import annotations

import math

import mdtraj
import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.errors import TemplateError, TrajectoryFileError
from knotmm.io.pdb import mdtraj_topology, write_pdb
from knotmm.knots.chirality import is_signed, unsigned_knot_type
from knotmm.knots.identify import identify_knot, topoly_available
from knotmm.knots.writhe import writhe
from knotmm.model.layout import ChainLayout
from knotmm.shapes import (
    BUILTIN_BRAIDS,
    braid_knot,
    build_template,
    check_template,
    checks,
    from_file,
    knotinfo,
    list_named_knots,
    minimal_beads,
    named_knot,
    torus_knot,
)
from knotmm.units import LJ_CUTOFF_FACTOR

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")
needs_knotinfo = pytest.mark.skipif(
    not knotinfo.knotinfo_available(), reason="database_knotinfo not installed"
)

BOND = 0.6
STERIC = LJ_CUTOFF_FACTOR * 0.5

TORUS_SHAPES = [(2, 3), (3, 2), (2, 5), (2, 7), (2, 9)]
TORUS_TYPES = {(2, 3): "3_1", (3, 2): "3_1", (2, 5): "5_1", (2, 7): "7_1", (2, 9): "9_1"}

SHAPES = [
    pytest.param({"kind": "torus", "p": p, "q": q}, TORUS_TYPES[(p, q)], id=f"T({p},{q})")
    for p, q in TORUS_SHAPES
] + [pytest.param({"kind": "knotinfo", "name": n}, n, id=n) for n in BUILTIN_BRAIDS]


def cfg(**knot):
    return RunConfig.from_dict({"knot": knot})


def bonds(x):
    return np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)


def closest_nonbonded(x):
    n = len(x)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    i, j = np.indices(d.shape)
    sep = np.abs(i - j)
    d[(sep <= 1) | (sep == n - 1)] = np.inf
    return d.min()


def assert_valid(x, knot_type):
    """Equal bonds at the bond length, no steric overlap, the right knot type."""
    assert x.dtype == np.float64 and x.shape[1] == 3
    np.testing.assert_allclose(bonds(x), BOND, rtol=1e-9)
    assert closest_nonbonded(x) >= STERIC
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=1e-12)
    if topoly_available():
        assert identify_knot(x) == knot_type


# -- the study's shapes and the experiments' knots ------------------------------------------
@pytest.mark.parametrize(("knot", "knot_type"), SHAPES)
def test_template_at_120_beads(knot, knot_type):
    tpl = build_template(cfg(beads=120, **knot))
    assert tpl.positions.shape == (120, 3)
    assert_valid(tpl.positions, knot_type)
    if topoly_available():  # unmirrored, every chiral one is right-handed: "+"
        assert tpl.knot_type == (knot_type if knot_type == "4_1" else f"+{knot_type}")
    assert tpl.writhe == pytest.approx(writhe(tpl.positions))
    assert tpl.resolved["knot.beads"] == 120
    assert tpl.resolved["knot.major_radius"] > 0


@pytest.mark.parametrize(("knot", "knot_type"), SHAPES)
def test_template_at_smallest_accepted_beads(knot, knot_type):
    n = minimal_beads(cfg(**knot))
    assert n is not None and 4 <= n <= 120
    tpl = build_template(cfg(beads=n, **knot))
    assert_valid(tpl.positions, knot_type)
    with pytest.raises(TemplateError, match=rf"knot\.beads={n - 1} is too few.*knot\.beads >= {n}"):
        build_template(cfg(beads=n - 1, **knot))


@pytest.mark.parametrize(("knot", "knot_type"), SHAPES)
def test_mirror_reverses_writhe(knot, knot_type):
    right = build_template(cfg(beads=90, **knot))
    left = build_template(cfg(beads=90, mirror=True, **knot))
    np.testing.assert_allclose(left.positions * [1, 1, -1], right.positions, atol=1e-12)
    assert left.writhe == pytest.approx(-right.writhe, abs=1e-9)
    if knot_type != "4_1":
        assert abs(right.writhe) > 1.0
        assert "mirror image" in left.description
        assert right.description.endswith(f", +{knot_type}") == (right.writhe > 0)
        assert left.description.endswith(f", -{knot_type} (mirror image)") == (left.writhe < 0)


def test_trefoil_is_right_handed_and_radius_near_estimate():
    # the helical path round the tube takes a larger share of a short chain
    for n, rel in ((40, 0.15), (120, 0.02)):
        tpl = build_template(cfg(beads=n, p=2, q=3))
        assert tpl.writhe > 0
        assert tpl.description == "T(2,3), +3_1"
        estimate = n * BOND / (2 * math.pi * 2)
        assert tpl.resolved["knot.major_radius"] == pytest.approx(estimate, rel=rel)
        assert tpl.resolved["knot.major_radius"] < estimate


def test_torus_shape_follows_the_parametrisation():
    a = 0.6
    tpl = build_template(cfg(beads=120, p=2, q=3, minor_radius=a))
    x = tpl.positions
    r0 = tpl.resolved["knot.major_radius"]
    rho = np.hypot(x[:, 0], x[:, 1])
    alpha = np.unwrap(np.arctan2(x[:, 1], x[:, 0]))
    alpha -= alpha[0]
    assert alpha[-1] == pytest.approx(4 * np.pi, abs=0.2)  # p = 2 loops round the z axis
    np.testing.assert_allclose(
        np.c_[rho - r0, x[:, 2]],
        a * np.c_[np.sin(1.5 * alpha), np.cos(1.5 * alpha)],
        atol=0.02,
    )


def test_t23_and_t32_are_different_shapes_of_one_knot():
    a, b = torus_knot(2, 3, 100), torus_knot(3, 2, 100)
    assert np.hypot(a[:, 0], a[:, 1]).mean() > 1.3 * np.hypot(b[:, 0], b[:, 1]).mean()
    if topoly_available():
        assert identify_knot(a) == identify_knot(b) == "3_1"


def test_geometry_functions_match_build_template():
    tpl = build_template(cfg(beads=80, p=2, q=5, minor_radius=0.7))
    np.testing.assert_allclose(torus_knot(2, 5, 80, minor_radius=0.7), tpl.positions)
    word = [1, -2, 1, -2]
    tpl = build_template(cfg(kind="braid", word=word, beads=90))
    np.testing.assert_allclose(braid_knot(word, 90), tpl.positions)
    np.testing.assert_allclose(named_knot("4_1", 90), tpl.positions)


def test_explicit_major_radius_is_kept_and_bonds_are_equal():
    x = torus_knot(2, 3, 100, major_radius=5.0)
    b = bonds(x)
    assert np.ptp(b) < 1e-9
    assert b[0] != pytest.approx(BOND, rel=0.005)
    r0 = build_template(cfg(beads=100, p=2, q=3)).resolved["knot.major_radius"]
    # issue 11, item 10: accepted, the bonds relax in the run
    tpl = build_template(cfg(beads=100, major_radius=5.0))
    np.testing.assert_allclose(tpl.positions, x, atol=1e-12)
    assert any("6.3% longer than model.bond_length=0.6; they relax" in n for n in tpl.notes)
    tpl = build_template(cfg(beads=100, major_radius=r0))
    assert not any("relax" in n for n in tpl.notes)
    np.testing.assert_allclose(bonds(tpl.positions), BOND, rtol=1e-6)
    # the recorded radius rebuilds the same template bit for bit (a run's run.toml)
    np.testing.assert_array_equal(tpl.positions, build_template(cfg(beads=100)).positions)


def test_study_start_with_explicit_radii_is_accepted_and_recorded():
    # issue 11, item 10: T(2,3) on a torus of radii 3.44 and 1.2 at N = 90, bonds 9 % short
    tpl = build_template(cfg(beads=90, p=2, q=3, major_radius=3.44, minor_radius=1.2))
    b = bonds(tpl.positions)
    # independent: the chain is 90 equal chords of the curve, each shorter than 0.6 d
    assert np.ptp(b) < 1e-9 and b[0] == pytest.approx(0.5444, abs=1e-4)
    assert tpl.facts["template_bond_range"] == pytest.approx([b.min(), b.max()])
    assert any("9.3% shorter" in n for n in tpl.notes)
    if topoly_available():
        assert tpl.knot_type == "+3_1"


def test_bonds_of_an_explicit_radius_start_relax_in_the_run():
    from knotmm.engine.simulation import Simulation
    from knotmm.model.system import ChainModel

    tpl = build_template(cfg(beads=90, p=2, q=3, major_radius=3.44, minor_radius=1.2))
    sim = Simulation(tpl.positions, ChainModel(), platform="Reference")
    sim.run(2.0, write_at_start=False)
    before = np.abs(bonds(tpl.positions) - BOND).max()
    after = np.abs(bonds(sim.positions) - BOND).max()
    assert after < 0.2 * before


def test_explicit_radius_refuses_only_deep_overlaps():
    # beads closer than lj_sigma: the steric force may not part them
    with pytest.raises(TemplateError, match=r"knot\.major_radius=1\.3 .*too tight.*closer than"):
        build_template(cfg(beads=90, p=2, q=3, major_radius=1.3, minor_radius=1.2))
    # bonds so long that the run would stop at once
    with pytest.raises(TemplateError, match=r"knot\.major_radius=12: bond .*run\.max_bond_length"):
        build_template(cfg(beads=40, p=2, q=3, major_radius=12.0, minor_radius=1.2))


def test_other_bond_length_and_sigma():
    data = {"knot": {"beads": 150, "p": 2, "q": 5}, "model": {"bond_length": 0.4}}
    tpl = build_template(RunConfig.from_dict(data))
    np.testing.assert_allclose(bonds(tpl.positions), 0.4, rtol=1e-9)
    data["model"]["lj_sigma"] = 1.2  # steric range 1.35 d > strand distance 1.2 d
    with pytest.raises(TemplateError, match="knot.minor_radius"):
        build_template(RunConfig.from_dict(data))


def test_braid_positive_generators_are_right_handed():
    assert writhe(braid_knot([1, 1, 1], 80)) > 2.5
    assert writhe(braid_knot([-1, -1, -1], 80)) < -2.5
    np.testing.assert_allclose(
        braid_knot([1, 1, 1], 80, mirror=True), braid_knot([1, 1, 1], 80) * [1, 1, -1]
    )


@needs_topoly
def test_braid_words_give_their_knots():
    assert identify_knot(braid_knot([1, 1, 1, -2, 1, -2], 150)) == "6_2"
    tpl = build_template(cfg(kind="braid", word=[1, 2, -1, 2], beads=80))
    assert tpl.knot_type == "0_1"
    assert any("unknot" in n for n in tpl.notes)


def test_builtin_names_without_knotinfo(monkeypatch):
    monkeypatch.setattr(knotinfo, "knotinfo_table", lambda: {})
    monkeypatch.setattr(knotinfo, "knotinfo_available", lambda: False)
    assert list_named_knots() == list(BUILTIN_BRAIDS)
    for name in BUILTIN_BRAIDS:
        assert named_knot(name, 120).shape == (120, 3)
    with pytest.raises(TemplateError, match=r"name='8_17'.*database_knotinfo"):
        named_knot("8_17", 120)


@needs_knotinfo
def test_builtin_words_are_knotinfo_words_and_more_knots_available():
    table = knotinfo.knotinfo_table()
    for name, word in BUILTIN_BRAIDS.items():
        assert table[name]["word"] == word
    names = list_named_knots()
    assert names[:3] == ["3_1", "4_1", "5_1"] and "13n_5110" in names and len(names) > 12000


@needs_knotinfo
@needs_topoly
@pytest.mark.parametrize(
    ("name", "beads", "hand"),
    [("8_17", 150, "amphichiral"), ("6_2", 120, "chiral"), ("6_3", 120, "amphichiral")],
)
def test_knotinfo_knots(name, beads, hand):
    tpl = build_template(cfg(kind="knotinfo", name=name, beads=beads))
    assert unsigned_knot_type(tpl.knot_type) == name
    assert is_signed(tpl.knot_type) == (hand == "chiral")  # only chiral knots carry a sign
    assert "KnotInfo" in tpl.description and tpl.description.endswith(f", {tpl.knot_type}")


@needs_knotinfo
@needs_topoly
def test_knots_the_polynomial_cannot_separate():
    # 10_132 shares its HOMFLY-PT polynomial with 5_1; 9_42 is chiral although HOMFLY-PT
    # does not see it: the tables decide
    tpl = build_template(cfg(kind="knotinfo", name="10_132", beads=130))
    assert unsigned_knot_type(tpl.knot_type) == "10_132"
    assert any("10_132 from 5_1" in n for n in tpl.notes)
    tpl = build_template(cfg(kind="knotinfo", name="9_42", beads=120))
    assert unsigned_knot_type(tpl.knot_type) == "9_42" and is_signed(tpl.knot_type)
    assert tpl.knot_type[0] == ("+" if tpl.writhe > 0 else "-") and tpl.knot_type in tpl.description
    assert not build_template(cfg(kind="knotinfo", name="5_1", beads=100)).notes


@pytest.mark.slow
@needs_knotinfo
@needs_topoly
@pytest.mark.parametrize("name", ["11a_1", "11n_34", "12a_100"])
def test_knotinfo_knots_beyond_ten_crossings(name):
    beads = minimal_beads(cfg(kind="knotinfo", name=name))
    tpl = build_template(cfg(kind="knotinfo", name=name, beads=beads))
    assert name in unsigned_knot_type(tpl.knot_type).split("|")


def test_named_knot_accepts_spellings():
    assert knotinfo.normalise_name(" 5.2 ") == "5_2"
    assert knotinfo.normalise_name("11A367") == "11a_367"
    np.testing.assert_allclose(named_knot("5.2", 100), named_knot("5_2", 100))


# -- checks and errors ------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("knot", "message"),
    [
        ({"p": 1, "q": 3}, r"T\(1,3\) is the unknot"),
        ({"p": 5, "q": 1}, r"T\(5,1\) is the unknot"),
        ({"kind": "braid"}, r"knot\.word is not set"),
        ({"kind": "braid", "word": []}, r"knot\.word=\[\]"),
        ({"kind": "braid", "word": [1, 0, 1]}, r"generator 0"),
        ({"kind": "braid", "word": [2, 2, 2]}, r"generator 1 never appears"),
        ({"kind": "knotinfo"}, r"knot\.name is not set"),
        ({"kind": "knotinfo", "name": "frobnicate"}, r"knot\.name='frobnicate'"),
        ({"kind": "file"}, r"knot\.path is not set"),
        (
            {"p": 2, "q": 5, "beads": 12},
            r"knot\.beads=12 is too few for T\(2,5\).*knot\.beads >= \d+",
        ),
        ({"p": 2, "q": 3, "minor_radius": 0.2}, r"knot\.minor_radius=0\.2 is too small"),
        (
            {"p": 2, "q": 3, "beads": 60, "major_radius": 0.5},
            r"knot\.major_radius=0\.5 is too small",
        ),
    ],
)
def test_bad_specifications_give_one_line_errors(knot, message):
    with pytest.raises(TemplateError, match=message) as info:
        build_template(cfg(**knot))
    assert "\n" not in str(info.value)


def test_public_functions_name_their_arguments():
    with pytest.raises(TemplateError, match=r"^p=2, q=4"):
        torus_knot(2, 4, 100)
    with pytest.raises(TemplateError, match=r"^beads=10 is too few"):
        torus_knot(2, 7, 10)
    with pytest.raises(TemplateError, match=r"^beads=2\.5"):
        torus_knot(2, 3, 2.5)
    with pytest.raises(TemplateError, match=r"^minor_radius=-1"):
        torus_knot(2, 3, 100, minor_radius=-1)
    with pytest.raises(TemplateError, match=r"^word="):
        braid_knot([1, "x"], 100)


def test_check_template_reports_overlap_and_bonds():
    x = torus_knot(2, 3, 100)
    report = check_template(x, BOND, 0.5, identify=False)
    assert report.ok and report.n_beads == 100
    assert report.bond_error < 1e-9 and report.min_distance >= report.steric_range
    squeezed = x.copy()
    squeezed[50] = squeezed[10] + [0.1, 0.0, 0.0]
    report = check_template(squeezed, BOND, 0.5, identify=False)
    assert not report.ok
    assert any("bond 49-50" in p for p in report.problems)
    assert any("beads 10 and 50" in p and "steric range" in p for p in report.problems)
    with pytest.raises(TemplateError, match="bond 49-50"):
        check_template(squeezed, BOND, 0.5, identify=False, raise_errors=True)


@needs_topoly
def test_check_template_catches_wrong_knot_type():
    report = check_template(torus_knot(2, 5, 100), BOND, 0.5, expected_knot="3_1")
    assert report.knot_type == "+5_1"
    assert any("not 3_1" in p for p in report.problems)


def test_knot_type_not_checked_without_topoly(monkeypatch):
    monkeypatch.setattr(checks, "topoly_available", lambda: False)
    tpl = build_template(cfg(beads=80))
    assert tpl.knot_type is None
    assert any("not checked: topoly not installed" in n for n in tpl.notes)


# -- perturbation -------------------------------------------------------------------------------
def test_perturbation_is_seeded():
    base = build_template(cfg(beads=100))
    a = build_template(cfg(beads=100, perturbation=0.05, seed=3))
    b = build_template(cfg(beads=100, perturbation=0.05, seed=3))
    c = build_template(cfg(beads=100, perturbation=0.05, seed=4))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.allclose(a.positions, c.positions)
    shift = a.positions - base.positions
    assert 0.03 < shift.std() < 0.07
    np.testing.assert_allclose(a.positions.mean(axis=0), 0.0, atol=1e-12)
    assert a.resolved["knot.seed"] == 3
    run_seeded = RunConfig.from_dict(
        {"knot": {"beads": 100, "perturbation": 0.05}, "run": {"seed": 3}}
    )
    np.testing.assert_array_equal(build_template(run_seeded).positions, a.positions)


def test_too_large_perturbation_is_refused():
    with pytest.raises(TemplateError, match=r"knot\.perturbation=0\.5 is too large"):
        build_template(cfg(beads=100, perturbation=0.5, seed=1))


# -- files ----------------------------------------------------------------------------------------
def test_write_pdb_has_every_bond_and_angstrom(tmp_path):
    x = torus_knot(2, 3, 50)
    path = tmp_path / "t.pdb"
    write_pdb(path, x)
    text = path.read_text()
    assert "CRYST1" not in text
    atoms = [line for line in text.splitlines() if line.startswith("ATOM")]
    assert len(atoms) == 50 and all(line[17:20] == "BEA" for line in atoms)
    assert float(atoms[0][30:38]) == pytest.approx(10 * x[0, 0], abs=1e-3)
    pairs = set()
    for line in text.splitlines():
        if line.startswith("CONECT"):
            serials = [int(line[i : i + 5]) for i in range(6, len(line.rstrip()), 5)]
            pairs.update(frozenset((serials[0], s)) for s in serials[1:])
    assert frozenset((50, 1)) in pairs
    assert pairs == {frozenset((i + 1, (i + 1) % 50 + 1)) for i in range(50)}
    traj = mdtraj.load(str(path))
    assert traj.topology.n_bonds == 50 and traj.unitcell_lengths is None


def test_file_template_round_trip(tmp_path):
    x = torus_knot(2, 5, 80)
    write_pdb(tmp_path / "topology.pdb", x)
    np.testing.assert_allclose(from_file(tmp_path / "topology.pdb"), x, atol=1e-3)
    frames = np.stack([x + [0.0, 0.0, 0.5 * k] for k in range(4)])
    mdtraj.Trajectory(frames, mdtraj_topology(80)).save_dcd(str(tmp_path / "traj.dcd"))
    np.testing.assert_allclose(from_file(tmp_path / "traj.dcd", frame=-1), frames[-1], atol=1e-4)
    (tmp_path / "traj.dcd").rename(tmp_path / "trajectory.dcd")  # a run directory
    np.testing.assert_allclose(from_file(tmp_path, frame=1), frames[1], atol=1e-4)
    (tmp_path / "trajectory.dcd").rename(tmp_path / "traj.dcd")
    tpl = build_template(cfg(kind="file", path=str(tmp_path / "traj.dcd"), frame=2))
    np.testing.assert_allclose(tpl.positions, x - x.mean(axis=0), atol=1e-4)
    assert tpl.resolved["knot.beads"] == 80
    assert any("knot.beads=90 ignored" in n for n in tpl.notes)
    if topoly_available():
        assert tpl.knot_type == "+5_1"
    mirrored = build_template(cfg(kind="file", path=str(tmp_path / "topology.pdb"), mirror=True))
    assert mirrored.writhe == pytest.approx(-tpl.writhe, abs=1e-3)


def test_file_errors(tmp_path):
    x = torus_knot(2, 3, 60)
    write_pdb(tmp_path / "ring.pdb", x)
    write_pdb(tmp_path / "small.pdb", torus_knot(2, 3, 50))
    mdtraj.Trajectory(np.stack([x] * 3), mdtraj_topology(60)).save_dcd(str(tmp_path / "ring.dcd"))
    data = (tmp_path / "ring.dcd").read_bytes()
    (tmp_path / "cut.dcd").write_bytes(data[:-100])
    (tmp_path / "stub.dcd").write_bytes(data[:40])
    (tmp_path / "junk.pdb").write_text("hello\n")
    (tmp_path / "alone").mkdir()
    (tmp_path / "alone" / "x.dcd").write_bytes(data)

    def fails(exc, match, **kw):
        with pytest.raises(exc, match=match) as info:
            from_file(**kw)
        assert "\n" not in str(info.value)

    fails(TrajectoryFileError, "file not found", path=tmp_path / "nope.pdb")
    fails(TrajectoryFileError, "is a directory without trajectory.dcd", path=tmp_path)
    fails(TrajectoryFileError, "no ATOM", path=tmp_path / "junk.pdb")
    (tmp_path / "ring.xyz").write_text("3\n\n")
    fails(TrajectoryFileError, r"expected a \.pdb or \.dcd", path=tmp_path / "ring.xyz")
    fails(TrajectoryFileError, "holds no topology", path=tmp_path / "alone" / "x.dcd")
    fails(
        TrajectoryFileError,
        r"60 atoms per frame but its topology small\.pdb has 50",
        path=tmp_path / "ring.dcd",
        topology=tmp_path / "small.pdb",
    )
    fails(
        TrajectoryFileError,
        r"truncated: its header claims 3 frames but only 2",
        path=tmp_path / "cut.dcd",
        frame=2,
        topology=tmp_path / "ring.pdb",
    )
    fails(
        TrajectoryFileError,
        "cannot be read as DCD",
        path=tmp_path / "stub.dcd",
        topology=tmp_path / "ring.pdb",
    )
    fails(
        TemplateError,
        r"frame=5 is out of range: ring\.dcd has 3 frames",
        path=tmp_path / "ring.dcd",
        frame=5,
    )
    fails(
        TrajectoryFileError,
        r"topology='.*missing\.pdb': file not found",
        path=tmp_path / "ring.dcd",
        topology=tmp_path / "missing.pdb",
    )
    # the complete frames of a truncated file are still usable
    np.testing.assert_allclose(
        from_file(tmp_path / "cut.dcd", frame=-1, topology=tmp_path / "ring.pdb"), x, atol=1e-4
    )
    with pytest.raises(TemplateError, match=r"knot\.frame=7 is out of range"):
        build_template(cfg(kind="file", path=str(tmp_path / "ring.dcd"), frame=7))


def test_file_with_overlapping_beads_is_refused(tmp_path):
    x = torus_knot(2, 3, 60)
    x[30] = x[0] + [0.2, 0.0, 0.0]
    write_pdb(tmp_path / "bad.pdb", x)
    with pytest.raises(TemplateError, match=r"knot\.path=.*beads 0 and 30 .*knot\.frame"):
        build_template(cfg(kind="file", path=str(tmp_path / "bad.pdb")))


# -- rings and open chains (issue 11, item 7) ---------------------------------------------
def _strip_conect(path):
    lines = [ln for ln in path.read_text().splitlines(True) if not ln.startswith("CONECT")]
    path.write_text("".join(lines))


def test_an_open_chain_file_starts_as_an_open_chain(tmp_path):
    """Issue 34: a file's open chain is read as written (it was refused, or closed)."""
    path = tmp_path / "open.pdb"
    x = torus_knot(2, 3, 60)
    write_pdb(path, x, closed=False)
    tpl = build_template(cfg(kind="file", path=str(path)))
    assert tpl.layout == ChainLayout((60,), (False,))
    assert tpl.knot_type is None and not tpl.parts
    np.testing.assert_allclose(tpl.positions, x - x.mean(axis=0), atol=1e-3)


def test_knot_closed_true_closes_an_open_chain_file_with_a_note(tmp_path):
    path = tmp_path / "open.pdb"
    x = torus_knot(2, 3, 60)
    write_pdb(path, x, closed=False)
    tpl = build_template(cfg(kind="file", path=str(path), closed=True))
    assert tpl.layout == ChainLayout.ring(60)
    assert any("knot.closed = true" in n and "closed here" in n for n in tpl.notes)
    np.testing.assert_allclose(tpl.positions, x - x.mean(axis=0), atol=1e-3)
    rod = np.c_[0.6 * np.arange(20), np.zeros(20), np.zeros(20)]
    write_pdb(tmp_path / "rod.pdb", rod, closed=False)
    with pytest.raises(TemplateError, match=r"bond 19-0 is 11\.400 d.*closure knot\.closed = "
                                            r"true adds.*leave knot\.closed unset") as info:
        build_template(cfg(kind="file", path=str(tmp_path / "rod.pdb"), closed=True))
    assert "\n" not in str(info.value)


def test_file_without_bonds_is_taken_as_a_ring_with_a_note(tmp_path):
    path = tmp_path / "bare.pdb"
    write_pdb(path, torus_knot(2, 3, 60))
    _strip_conect(path)
    tpl = build_template(cfg(kind="file", path=str(path)))
    assert any("lists no bonds" in n and "ring" in n for n in tpl.notes)


def test_closed_file_gives_no_ring_note(tmp_path):
    path = tmp_path / "ring.pdb"
    write_pdb(path, torus_knot(2, 3, 60))
    tpl = build_template(cfg(kind="file", path=str(path)))
    assert not any("bond" in n and "ring" in n for n in tpl.notes)


def test_the_unknot_is_a_flat_circle_of_equal_chords():
    from knotmm.config import RunConfig
    from knotmm.shapes.builder import build_template

    for name in ("0_1", "unknot"):
        tpl = build_template(RunConfig.from_dict({"knot": {"kind": "knotinfo", "name": name,
                                                          "beads": 48}}), identify="skip")
        x = tpl.positions
        radius = 0.6 / (2 * np.sin(np.pi / 48))  # the regular 48-gon with sides l0
        np.testing.assert_allclose(np.linalg.norm(x[:, :2], axis=1), radius, rtol=1e-9)
        np.testing.assert_allclose(x[:, 2], 0.0, atol=1e-12)
        assert tpl.resolved["knot.name"] == "0_1"
