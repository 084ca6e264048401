"""Loading run directories and bare DCD/PDB pairs; clear errors on broken input."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis import load_run
from knotmm.errors import ConfigError, TrajectoryFileError

DT = 0.5


@pytest.fixture(scope="module")
def positions():
    times = np.arange(41) * DT
    return vortex_knot_positions(times, n_beads=30, rho0=1.5, swirl_amplitude=0.3)


@pytest.fixture
def run(tmp_path, positions):
    config = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
    return write_run_directory(tmp_path / "run", positions, DT, config)


def test_run_directory_in_model_units(run, positions):
    data = load_run(run)
    assert data.positions.shape == positions.shape
    np.testing.assert_allclose(data.positions, positions, atol=1e-4)  # float32 in Angstrom
    np.testing.assert_allclose(data.times, np.arange(41) * DT)
    assert data.frame_interval == DT
    assert data.n_beads == 30 and data.n_frames == 41
    assert len(data.bonds) == 30 and {0, 29} in [set(b) for b in data.bonds.tolist()]
    assert data.get("knot.q") == 3 and data.get("knot.missing", 7) == 7
    assert data.notes == []
    # the DCD really holds Angstrom: 10 per d
    from mdtraj.formats import DCDTrajectoryFile

    with DCDTrajectoryFile(str(run / "trajectory.dcd")) as fh:
        raw = fh.read()[0]
    np.testing.assert_allclose(raw[3], 10 * positions[3], atol=1e-3)


def _zero_header_step(path):
    """Set the DCD header's DELTA (float32 at byte 44) to 0: a file with no time step."""
    with open(path, "r+b") as fh:
        fh.seek(44)
        fh.write(b"\0\0\0\0")


def test_bare_dcd_takes_its_headers_interval_else_needs_frame_interval(run, tmp_path):
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(run / "trajectory.dcd", bare / "knot.dcd")
    shutil.copy(run / "topology.pdb", bare / "chain.pdb")
    data = load_run(bare / "knot.dcd")  # no run.toml: the header's NSAVC x DELTA
    assert data.frame_interval == DT and data.times[-1] == 40 * DT
    assert any("from the header of knot.dcd" in n for n in data.notes)
    _zero_header_step(bare / "knot.dcd")
    with pytest.raises(ConfigError, match="header has no time step.*--frame-interval"):
        load_run(bare / "knot.dcd")
    data = load_run(bare / "knot.dcd", frame_interval=2.0)  # the only PDB beside it
    assert data.frame_interval == 2.0 and data.times[-1] == 80.0
    assert data.config == {} and data.run_file is None
    other = tmp_path / "elsewhere.pdb"
    shutil.move(bare / "chain.pdb", other)
    with pytest.raises(TrajectoryFileError, match="--topology"):
        load_run(bare / "knot.dcd", frame_interval=2.0)
    assert load_run(bare / "knot.dcd", frame_interval=2.0, topology=other).n_beads == 30


def test_an_openmm_dcd_reporters_file_states_its_interval(run, tmp_path):
    """OpenMM's DCDFile with a 0.002 ps step and a frame every 250 steps: 0.5 ps between
    frames, as MDAnalysis reads the same header (dt = NSAVC x DELTA x 0.04888821 ps)."""
    import openmm.app as app

    from knotmm.model.topology import bead_topology

    x = load_run(run).positions
    with open(tmp_path / "reporter.dcd", "wb") as fh:
        dcd = app.DCDFile(fh, bead_topology(30), 0.002, interval=250)
        for frame in x[:5]:
            dcd.writeModel(frame)
    shutil.copy(run / "topology.pdb", tmp_path / "reporter.pdb")
    data = load_run(tmp_path / "reporter.dcd")
    assert data.frame_interval == 0.5 and data.n_frames == 5
    np.testing.assert_allclose(data.positions, x[:5], atol=1e-4)


def test_frame_interval_argument_wins(run):
    data = load_run(run, frame_interval=1.0)
    assert data.frame_interval == 1.0
    assert any("run.toml says" in n for n in data.notes)


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan")])
def test_bad_frame_interval(run, value):
    with pytest.raises(ConfigError, match="--frame-interval"):
        load_run(run, frame_interval=value)


def test_missing_path(tmp_path):
    with pytest.raises(TrajectoryFileError, match="no such run directory"):
        load_run(tmp_path / "nope")


def test_directory_without_trajectory(tmp_path):
    with pytest.raises(TrajectoryFileError, match="no trajectory.dcd"):
        load_run(tmp_path)


def test_not_a_dcd(run):
    with pytest.raises(TrajectoryFileError, match="expected a run directory or a .dcd"):
        load_run(run / "run.toml")


def test_missing_topology(run):
    (run / "topology.pdb").unlink()
    with pytest.raises(TrajectoryFileError, match="no topology found"):
        load_run(run)


def test_truncated_dcd_keeps_complete_frames(run):
    path = run / "trajectory.dcd"
    data = path.read_bytes()
    path.write_bytes(data[:-50])  # cut inside the last frame
    loaded = load_run(run)
    assert loaded.n_frames == 40
    assert any("interrupted" in n for n in loaded.notes)
    assert any("stopped early" in n for n in loaded.notes)


@pytest.mark.parametrize("keep", [0, 40])
def test_dcd_cut_in_header(run, keep):
    path = run / "trajectory.dcd"
    path.write_bytes(path.read_bytes()[:keep])
    with pytest.raises(TrajectoryFileError, match="trajectory.dcd: cannot be read"):
        load_run(run)


def test_mismatched_topology(run, tmp_path):
    other = write_run_directory(
        tmp_path / "other", np.zeros((2, 12, 3)) + np.arange(12)[:, None], DT
    )
    shutil.copy(other / "topology.pdb", run / "topology.pdb")
    with pytest.raises(TrajectoryFileError, match="30 beads per frame but .* has 12"):
        load_run(run)


def test_mismatched_run_file(run):
    text = (run / "run.toml").read_text().replace("beads = 30", "beads = 31")
    (run / "run.toml").write_text(text)
    with pytest.raises(TrajectoryFileError, match="knot.beads = 31"):
        load_run(run)


def test_broken_run_file(run):
    (run / "run.toml").write_text("[knot\nbeads = ")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_run(run)


def test_broken_topology(run):
    (run / "topology.pdb").write_text("this is not a PDB\n")
    with pytest.raises(TrajectoryFileError, match="topology"):
        load_run(run)


def test_open_chain_is_analysed_as_a_ring_with_a_note(run):
    """A PDB without the ring-closing CONECT (issue 11, item 7): loaded, with a note saying
    that the ring is closed by assumption (the closed ring stays the default)."""
    top = run / "topology.pdb"
    lines = top.read_text().splitlines()
    # drop the closing bond 29-0 from the CONECT records (PDB serials are 1-based: 30 <-> 1)
    kept = []
    for line in lines:
        if line.startswith("CONECT"):
            fields = line.split()
            serials = [int(f) for f in fields[1:]]
            if serials[0] in (1, 30):
                other = 30 if serials[0] == 1 else 1
                serials = [serials[0]] + [s for s in serials[1:] if s != other]
            line = "CONECT" + "".join(f"{s:5d}" for s in serials)
        kept.append(line)
    top.write_text("\n".join(kept) + "\n")
    data = load_run(run)
    assert any("no bond closing the ring (29-0)" in note for note in data.notes), data.notes
    assert data.n_beads == 30
