"""The analysis by object (issue 34): each chain measured as what it is, the system as what
it is, against computations written here.

* a system of three chains (a right-handed and a left-handed trefoil and an open rod): each
  chain's observables equal those of its beads analysed alone, and the known speeds, radii
  and shapes; the system has no one rho0, ACN or Rg (n/a with the reason);
* an open filament never gets a ring's knot type (no identification is even tried, so no
  "change" can cut its window) or torus rows;
* a torus link T(2,4) is analysed as the torus state it is (its swirl measured on all its
  beads, the torus formulas applied), no note advises --p/--q;
* a nearly rigid straight rod falling broadside (a short real run) falls at the speed of a
  rigid body in the RPY mobility, solved here from the dense tensor;
* the elasto-gravitation number B = N^3 F0 l0 / A of known chains.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_model import rpy_dense
from same_values import assert_same_values
from synthetic import vortex_knot_positions, write_run_directory

import knotmm.analysis.core as core
from knotmm.analysis.core import analyze, analyze_run
from knotmm.analysis.knot_types import torus_link
from knotmm.analysis.objects import OPEN_CHAIN, RING_KEYS, SEPARATE
from knotmm.errors import ConfigError
from knotmm.io.run_data import RunData
from knotmm.io.rundir import read_facts
from knotmm.model.layout import ChainLayout
from knotmm.model.parameters import elasto_gravitation_number

DT = 0.5
TIMES = np.arange(301) * DT
MODEL = {"gravity": 1.0, "bond_length": 0.6, "bending_stiffness": 5.0}


def rod_positions(times, n=20, bond=0.6, speed=1.2, tilt0=10.0, relax=50.0, centre=(0, 0, 0)):
    """An open straight rod along x, its end-to-end vector tilted ``tilt0 exp(-t/relax)``
    degrees out of the horizontal (about y), falling at ``speed``."""
    s = (np.arange(n) - (n - 1) / 2) * bond
    tilt = np.radians(tilt0) * np.exp(-np.asarray(times) / relax)
    x = np.zeros((len(times), n, 3))
    x[..., 0] = np.cos(tilt)[:, None] * s
    x[..., 2] = np.sin(tilt)[:, None] * s - speed * np.asarray(times)[:, None]
    return x + np.asarray(centre, dtype=float)


def bonds_of(layout: ChainLayout) -> np.ndarray:
    return layout.bonds()


def row_labels(table: str) -> list[str]:
    """The first column of the analysis table's rows (its notes left out)."""
    return [line.split("  ")[0] for line in table.splitlines() if not line.startswith("note:")]


def three_chain_run():
    """Trefoil A (60 beads), its mirror image B (48 beads, other speed and periods), open rod
    C (20 beads) above them: a ``[[chains]]`` run as run.toml records it."""
    a = vortex_knot_positions(TIMES, n_beads=60, rho0=3.0, velocity=2.0, tau_swirl=10.0,
                              tau_rot=300.0) + [-8.0, 0.0, 0.0]
    b = vortex_knot_positions(TIMES, n_beads=48, rho0=2.5, velocity=1.6, tau_swirl=8.0,
                              tau_rot=-200.0, mirror=True) + [8.0, 0.0, 0.0]
    c = rod_positions(TIMES, centre=(0.0, 8.0, 6.0))
    layout = ChainLayout((60, 48, 20), (True, True, False))
    entries = [{"kind": "torus", "p": 2, "q": 3, "beads": 60, "offset": [-8.0, 0.0, 0.0]},
               {"kind": "torus", "p": 2, "q": 3, "beads": 48, "mirror": True},
               {"kind": "straight", "beads": 20}]
    config = {
        "chains": entries, "model": dict(MODEL),
        "knotmm": {"layout": layout.to_record(),
                   "chains": [{"id": cid, "beads": n, "closed": ring} for cid, n, ring
                              in zip(layout.ids, layout.lengths, layout.closed, strict=True)]},
    }
    x = np.concatenate([a, b, c], axis=1)
    return RunData.from_arrays(x, DT, config=config, bonds=bonds_of(layout)), layout, entries


_same = assert_same_values


@pytest.fixture(scope="module")
def three():
    data, layout, entries = three_chain_run()
    return data, layout, entries, analyze(data, knot_samples=0).to_dict()


def test_each_chain_of_three_equals_its_beads_analysed_alone(three):
    data, layout, entries, d = three
    assert [c["id"] for c in d["chains"]] == ["A", "B", "C"]
    for c, sl, ring, entry in zip(d["chains"], layout.slices(), layout.closed, entries,
                                  strict=True):
        knot = {k: v for k, v in entry.items() if k not in ("offset", "rotation")}
        alone = RunData.from_arrays(
            data.positions[:, sl], DT, config={"knot": {**knot, "closed": ring},
                                               "model": dict(MODEL)},
            bonds=ChainLayout((sl.stop - sl.start,), (ring,)).bonds())
        own = analyze(alone, knot_samples=0).to_dict()
        for key in c:
            if key not in ("id", "beads", "closed", "notes"):
                _same(own[key], c[key], f"chain {c['id']}: {key}")


def test_each_chain_has_its_known_speed_radius_and_size(three):
    data, layout, _, d = three
    a, b, c = d["chains"]
    assert a["sedimentation_velocity"] == pytest.approx(2.0, rel=1e-9)
    assert b["sedimentation_velocity"] == pytest.approx(1.6, rel=1e-9)
    assert c["sedimentation_velocity"] == pytest.approx(1.2, rel=1e-9)
    for row, sl in zip((a, b), layout.slices()[:2], strict=True):
        t0, t1 = row["window"]
        frames = slice(int(round(t0 / DT)), int(round(t1 / DT)) + 1)
        x = data.positions[frames, sl]
        rel = x - x.mean(axis=1, keepdims=True)
        rg = np.sqrt((rel**2).sum(axis=2).mean(axis=1)).mean()  # Rg of the window, averaged
        rho0 = np.hypot(rel[..., 0], rel[..., 1]).mean()
        assert row["radius_of_gyration"] == pytest.approx(rg, rel=1e-9)
        assert row["major_radius"] == pytest.approx(rho0, rel=1e-9)
        assert row["tau_sed"] == pytest.approx(2 * rho0 / row["sedimentation_velocity"], rel=1e-9)
    assert a["tau_swirl"] == pytest.approx(10.0, rel=1e-3)
    assert b["tau_swirl"] == pytest.approx(8.0, rel=1e-3)
    assert a["handedness"] == "right" and b["handedness"] == "left"
    # the rod: its end-to-end vector, 11.4 d long, tilted 10 degrees from the horizontal
    assert c["end_to_end_length_start"] == pytest.approx(19 * 0.6, rel=1e-12)
    assert c["end_to_end_angle_to_vertical_start_deg"] == pytest.approx(80.0, rel=1e-9)
    tilt_end = 10.0 * math.exp(-TIMES[-1] / 50.0)
    assert c["end_to_end_angle_to_vertical_end_deg"] == pytest.approx(90.0 - tilt_end, rel=1e-9)
    # B = N^3 F0 l0 / A = 0.12 N^3 with the study's values
    assert [x["elasto_gravitation_number"] for x in d["chains"]] == pytest.approx(
        [0.12 * 60**3, 0.12 * 48**3, 0.12 * 20**3], rel=1e-12)


def test_the_system_of_separate_chains_has_no_one_structure(three):
    data, layout, _, d = three
    # the centre of mass of all 128 beads: (60 * 2 + 48 * 1.6 + 20 * 1.2) / 128
    assert d["sedimentation_velocity"] == pytest.approx((120 + 76.8 + 24) / 128, rel=1e-9)
    for key in ("major_radius", "tau_sed", "average_crossing_number", "radius_of_gyration",
                "tau_swirl", "tau_rot", "knot_type"):
        assert d[key] is None and d["not_applicable"][key] == SEPARATE, key
    assert d["elasto_gravitation_number"] is None
    assert d["system"]["kind"] == "separate chains"
    table = analyze(data, knot_samples=0).summary()
    rows = row_labels(table)
    assert "rho0 [d]" not in rows and "average crossing number" not in rows
    assert "n/a" in rows and f"({SEPARATE})" in table
    # the pairs: the line between centres against the vertical, the axes' angle
    pairs = {p["chains"]: p for p in d["system"]["pairs"]}
    sl = layout.slices()
    e = data.positions[0, sl[2]].mean(axis=0) - data.positions[0, sl[0]].mean(axis=0)
    assert pairs["A-C"]["separation_angle_to_vertical_start_deg"] == pytest.approx(
        math.degrees(math.acos(abs(e[2]) / np.linalg.norm(e))), rel=1e-9)
    assert pairs["A-B"]["separation_angle_to_vertical_start_deg"] == pytest.approx(90.0)
    # A's axis is its normal (vertical), C's its long axis (10 degrees from the horizontal)
    assert pairs["A-C"]["axes"] == "normal-long axis"
    assert pairs["A-C"]["axis_angle_start_deg"] == pytest.approx(80.0, abs=0.5)
    assert d["system"]["linking_numbers"] == {"A-B": 0}


def open_trefoil_run(n=60):
    """A swirling T(2,3) cut open between its last bead and its first."""
    x = vortex_knot_positions(TIMES, n_beads=n, rho0=3.0, velocity=2.0, tau_swirl=10.0,
                              tau_rot=300.0)
    layout = ChainLayout((n,), (False,))
    config = {"knot": {"kind": "torus", "p": 2, "q": 3, "beads": n, "closed": False},
              "model": dict(MODEL)}
    return RunData.from_arrays(x, DT, config=config, bonds=layout.bonds())


def test_an_open_filament_gets_no_knot_type_and_no_torus_rows(monkeypatch):
    def no_identification(*args, **kwargs):
        raise AssertionError("an open chain's knot type was looked for")

    monkeypatch.setattr(core, "knot_types", no_identification)
    data = open_trefoil_run()
    result = analyze(data, knot_samples=40)
    d = result.to_dict()
    for key in RING_KEYS:
        assert d[key] is None and d["not_applicable"][key] == OPEN_CHAIN, key
    assert d["tilt"] is None and d["spectra"] is None and d["fit"] is None
    # the window is not cut: the whole run, as the shape never changes
    assert d["window"] == [0.0, TIMES[-1]]
    # what an open chain has: its speed, size and end-to-end vector
    assert d["sedimentation_velocity"] == pytest.approx(2.0, rel=1e-9)
    e = np.linalg.norm(data.positions[:, -1] - data.positions[:, 0], axis=1)
    assert d["end_to_end_length"] == pytest.approx(e.mean(), rel=1e-9)
    assert d["elasto_gravitation_number"] == pytest.approx(0.12 * 60**3, rel=1e-12)
    table = result.summary()
    for row in ("rho0 [d]", "tau_swirl [tau_d]", "torus axis vs gravity", "knot type"):
        assert row not in row_labels(table), row
    assert "open chain: no knot type" in table and f"({OPEN_CHAIN})" in table
    assert not any("--p" in n for n in d["notes"])
    with pytest.raises(ConfigError, match="open chain"):
        analyze(data, p=2, q=3, knot_samples=0)


def test_an_open_chain_run_directory_reads_without_a_missing_ring_bond(tmp_path, capsys):
    from knotmm.cli.main import main

    x = rod_positions(TIMES[:81])
    layout = ChainLayout((20,), (False,))
    run = write_run_directory(tmp_path / "rod", x, DT,
                              config={"knot": {"kind": "straight", "beads": 20},
                                      "model": dict(MODEL)}, layout=layout)
    assert main(["analyze", str(run), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "no bond closing the ring" not in out and "open chain: no knot type" in out
    assert "end-to-end length [d]" in out and "B = N^3 F0 l0/A" in out
    d = analyze_run(run, plots=True).to_dict()
    assert "analysis_spectrum.png" not in d["plots"]
    assert d["knot_type"] is None and d["major_radius"] is None
    assert d["elasto_gravitation_number"] == pytest.approx(960.0, rel=1e-12)


def torus_link_run(m=40):
    """The torus link T(2,4) swirling as one torus: two rings T(1,2), swirl phases pi apart."""
    kw = dict(n_beads=m, p=1, q=2, rho0=4.0, swirl_amplitude=0.6, velocity=2.0,
              tau_swirl=10.0, tau_rot=150.0)
    x = np.concatenate([vortex_knot_positions(TIMES, **kw),
                        vortex_knot_positions(TIMES, phase=np.pi, **kw)], axis=1)
    layout = ChainLayout((m, m), (True, True))
    config = {"knot": {"kind": "torus", "p": 2, "q": 4, "beads": 2 * m}, "model": dict(MODEL),
              "knotmm": {"link": "T(2,4)", "layout": layout.to_record(),
                         "chains": [{"id": "A", "beads": m, "closed": True},
                                    {"id": "B", "beads": m, "closed": True}]}}
    return RunData.from_arrays(x, DT, config=config, bonds=layout.bonds())


def test_a_torus_link_is_analysed_as_the_torus_state_it_is():
    result = analyze(torus_link_run(), knot_samples=0)
    d = result.to_dict()
    assert d["system"]["kind"] == "link" and d["system"]["linking_numbers"] == {"A-B": 2}
    assert (d["p"], d["q"], d["p_source"]) == (2, 4, "run file")
    assert d["tau_swirl"] == pytest.approx(10.0, rel=1e-3)
    assert d["tau_swirl_source"] == "the link's beads"
    assert d["tau_rot"] == pytest.approx(150.0, rel=1e-3)
    assert d["major_radius"] == pytest.approx(4.0, rel=1e-3)
    assert d["tau_swirl_over_tau_sed"] == pytest.approx(10.0 / (2 * 4.0 / 2.0), rel=2e-3)
    assert d["fit_quality"]["r2"] > 0.999 and d["fit"]["swirl_amplitude"] == pytest.approx(0.6)
    for c in d["chains"]:  # each ring swirls with the link
        assert c["tau_swirl"] == pytest.approx(10.0, rel=1e-3)
    assert not any("--p" in n or "winds" in n for n in d["notes"]), d["notes"]
    assert d["knot_type"] is None and "a link" in d["not_applicable"]["knot_type"]
    assert "tau_swirl [tau_d]" in result.summary()


def test_which_systems_are_torus_links():
    rings = [(slice(0, 30), True), (slice(30, 60), True)]

    def data(config, chains=rings):
        n = chains[-1][0].stop
        return RunData.from_arrays(np.zeros((2, n, 3)), 1.0, config=config)

    assert torus_link(data({"knot": {"kind": "knotinfo", "name": " Hopf"}}), rings) == (2, 2)
    assert torus_link(data({"knot": {"kind": "torus", "p": 2, "q": 4}}), rings) == (2, 4)
    assert torus_link(data({"knot": {"kind": "torus", "p": 2, "q": 3}}), rings) is None
    assert torus_link(data({"knot": {"kind": "knotinfo", "name": "whitehead"}}), rings) is None
    assert torus_link(data({"knot": {"kind": "torus", "p": 2, "q": 4},
                            "chains": [{}, {}]}), rings) is None
    cut = [(slice(0, 30), True), (slice(30, 60), False)]
    assert torus_link(data({"knot": {"kind": "torus", "p": 2, "q": 4}}, cut), cut) is None


def _rigid_body_speed(x: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Velocity of a rigid body of beads in the RPY mobility (docs/model.md), from the
    dense tensor: bead velocities ``U + Omega x r_i`` need forces ``f = mu^-1 K (U, Omega)``;
    their sum and torque must be the applied ones, so ``(U, Omega) = (K^T mu^-1 K)^-1 K^T F``."""
    n = len(x)
    r = x - x.mean(axis=0)
    k = np.zeros((3 * n, 6))
    for i in range(n):
        k[3 * i:3 * i + 3, :3] = np.eye(3)
        rx, ry, rz = r[i]
        k[3 * i:3 * i + 3, 3:] = -np.array([[0, -rz, ry], [rz, 0, -rx], [-ry, rx, 0]])
    resistance = k.T @ np.linalg.solve(rpy_dense(x), k)
    # beads on a line do not resist spinning about it: the least-squares solution
    return np.linalg.lstsq(resistance, k.T @ force.ravel(), rcond=1e-12)[0][:3]


def test_a_stiff_rod_falling_broadside_falls_at_its_rigid_body_rpy_speed(tmp_path):
    from knotmm.config import RunConfig
    from knotmm.workflow import run

    settings = {"knot": {"kind": "straight", "beads": 20},
                "model": {"bending_stiffness": 5000.0, "bond_stiffness": 5000.0},
                "run": {"duration": 5.0, "topology_check_interval": 0.0},
                "output": {"frame_interval": 0.25, "checkpoint_interval": 5.0}}
    run(RunConfig.from_dict(settings), directory=tmp_path / "rod", progress=False)
    result = analyze_run(tmp_path / "rod", plots=False)
    x0 = result.data.positions[0]
    force = np.zeros_like(x0)
    force[:, 2] = -1.0  # F0 on every bead, downwards
    u = _rigid_body_speed(x0, force)
    assert np.abs(u[:2]).max() < 1e-12  # broadside: straight down
    assert result.sedimentation_velocity == pytest.approx(-u[2], rel=1e-4)
    # the naive mean of mu F (beads free to move apart) is the start's velocity, not the
    # rod's: 3.6 % faster, far outside the tolerance above
    naive = -(rpy_dense(x0) @ force.ravel())[2::3].mean()
    assert naive / -u[2] - 1 > 0.03
    d = result.to_dict()
    assert d["end_to_end_angle_to_vertical_deg"] == pytest.approx(90.0, abs=0.1)
    assert d["elasto_gravitation_number"] == pytest.approx(20**3 * 0.6 / 5000.0, rel=1e-12)
    assert read_facts(tmp_path / "rod")["elasto_gravitation_number"] == pytest.approx(0.96)


def test_run_toml_records_the_elasto_gravitation_number_of_every_chain(tmp_path):
    from knotmm.config import RunConfig
    from knotmm.workflow import run

    settings = {"chains": [{"kind": "straight", "beads": 10, "offset": [0.0, -3.0, 0.0]},
                           {"kind": "torus", "p": 2, "q": 3, "beads": 40,
                            "offset": [0.0, 6.0, 0.0]}],
                "model": {"bending_stiffness": 50.0},
                "run": {"duration": 0.25, "topology_check_interval": 0.0},
                "output": {"frame_interval": 0.25, "checkpoint_interval": 0.25}}
    run(RunConfig.from_dict(settings), directory=tmp_path / "two", progress=False)
    facts = read_facts(tmp_path / "two")  # one per chain, in the layout's order
    assert facts["layout"]["lengths"] == [10, 40]
    assert facts["elasto_gravitation_numbers"] == pytest.approx(
        [10**3 * 0.6 / 50.0, 40**3 * 0.6 / 50.0], rel=1e-12)


def test_the_elasto_gravitation_number_of_known_chains():
    assert elasto_gravitation_number(20, 1.0, 0.6, 5.0) == pytest.approx(960.0, rel=1e-15)
    assert elasto_gravitation_number(90, 2.0, 0.5, 50.0) == pytest.approx(
        90**3 * 2.0 * 0.5 / 50.0, rel=1e-15)
    assert math.isinf(elasto_gravitation_number(20, 1.0, 0.6, 0.0))
    # without a run file there is no B, and a note says why
    bare = RunData.from_arrays(open_trefoil_run().positions, DT,
                               bonds=ChainLayout((60,), (False,)).bonds())
    d = analyze(bare, knot_samples=0).to_dict()
    assert d["elasto_gravitation_number"] is None
    assert any("elasto-gravitation number B not known" in n for n in d["notes"])
