"""DCD layout, frame counts and truncation, measured one way (knotmm.io.dcd)."""

from __future__ import annotations

import numpy as np
import pytest
from mdtraj.formats import DCDTrajectoryFile

from knotmm.errors import TrajectoryFileError
from knotmm.io.dcd import dcd_layout, read_dcd, truncate_dcd


def _write(path, n_frames, n_atoms, cell=False):
    xyz = np.arange(n_frames * n_atoms * 3, dtype=np.float32).reshape(n_frames, n_atoms, 3)
    with DCDTrajectoryFile(str(path), "w") as fh:
        if cell:
            fh.write(xyz, cell_lengths=np.full((n_frames, 3), 50.0),
                     cell_angles=np.full((n_frames, 3), 90.0))
        else:
            fh.write(xyz)
    return xyz


@pytest.mark.parametrize("cell", [False, True])
def test_layout_matches_the_file_size_and_mdtraj(tmp_path, cell):
    path = tmp_path / "t.dcd"
    _write(path, 7, 11, cell)
    layout = dcd_layout(path)
    # independent: a frame is three Fortran records of n_atoms float32 (4 + 4 n + 4 bytes),
    # plus a 56-byte unit-cell record when there is one
    frame = 3 * (4 + 4 * 11 + 4) + (56 if cell else 0)
    assert layout.frame_bytes == frame
    assert layout.header_bytes + 7 * frame == path.stat().st_size
    assert (layout.n_atoms, layout.claimed_frames, layout.complete_frames) == (11, 7, 7)
    assert not layout.truncated


def test_a_frame_cut_short_is_seen_and_cut_back(tmp_path):
    path = tmp_path / "t.dcd"
    xyz = _write(path, 6, 5)
    path.write_bytes(path.read_bytes()[:-30])  # a writer killed inside the last frame
    layout = dcd_layout(path)
    assert (layout.claimed_frames, layout.complete_frames) == (6, 5) and layout.truncated
    got, notes = read_dcd(path)
    np.testing.assert_array_equal(got, xyz[:5])
    assert len(notes) == 1 and "claims 6 frames but only 5" in notes[0]
    truncate_dcd(path, 3)
    layout = dcd_layout(path)
    assert (layout.claimed_frames, layout.complete_frames, layout.partial_bytes) == (3, 3, 0)
    with DCDTrajectoryFile(str(path)) as fh:  # mdtraj agrees, without a complaint
        again, _, _ = fh.read()
    np.testing.assert_array_equal(again, xyz[:3])


def test_truncation_refuses_to_invent_frames(tmp_path):
    path = tmp_path / "t.dcd"
    _write(path, 2, 5)
    with pytest.raises(TrajectoryFileError, match="holds 2 whole frames but the checkpoint "
                                                  "counts 4"):
        truncate_dcd(path, 4)
    with pytest.raises(TrajectoryFileError, match="missing"):
        truncate_dcd(tmp_path / "none.dcd", 1)


@pytest.mark.parametrize("keep", [0, 5, 60, 100])
def test_a_damaged_header_is_one_clear_error(tmp_path, keep):
    path = tmp_path / "t.dcd"
    _write(path, 2, 5)
    path.write_bytes(path.read_bytes()[:keep])
    with pytest.raises(TrajectoryFileError, match="not a DCD|cut inside its DCD header"):
        dcd_layout(path)


# -- issue 23, item 3: paths with spaces and non-ASCII characters ------------------------------
#: A folder name with spaces, accented letters and a symbol outside Latin-1, and one holding
#: a byte that is not UTF-8 (Python sees it as a lone surrogate, ``os.fsencode`` restores it).
ODD_NAMES = ["dir with spaces/ünïcødé ☃ run", "bytes \udcff not utf-8"]


@pytest.mark.parametrize("name", ODD_NAMES)
def test_read_and_write_dcd_in_a_unicode_path(tmp_path, name):
    from knotmm.io.dcd import write_dcd

    folder = tmp_path / name
    folder.mkdir(parents=True)
    positions = np.arange(4 * 5 * 3, dtype=np.float64).reshape(4, 5, 3) / 7.0
    write_dcd(folder / "trajectory.dcd", positions)  # mdtraj: UnicodeEncodeError before
    xyz, notes = read_dcd(folder / "trajectory.dcd")
    assert notes == []
    np.testing.assert_allclose(xyz, positions * 10.0, rtol=1e-6)
    assert sorted(p.name for p in folder.iterdir()) == ["trajectory.dcd"]  # no temporary left


@pytest.mark.parametrize("name", ODD_NAMES)
def test_a_start_frame_is_read_from_a_dcd_in_a_unicode_path(tmp_path, name):
    from knotmm.io.pdb import write_pdb
    from knotmm.io.structure import read_structure

    folder = tmp_path / name
    folder.mkdir(parents=True)
    positions = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 6, 12)]) * 2
    write_pdb(folder / "topology.pdb", positions)
    _write(tmp_path / "ascii.dcd", 3, 12)  # mdtraj writes an ASCII name; then moved
    (tmp_path / "ascii.dcd").rename(folder / "trajectory.dcd")
    structure = read_structure(folder / "trajectory.dcd", frame=-1)
    assert structure.positions.shape == (12, 3)


def test_a_damaged_dcd_in_a_unicode_path_names_the_path_as_text(tmp_path):
    folder = tmp_path / "ünïcødé ☃"
    folder.mkdir()
    (folder / "trajectory.dcd").write_bytes(b"not a dcd at all")
    with pytest.raises(TrajectoryFileError) as info:
        read_dcd(folder / "trajectory.dcd")
    assert "b'" not in str(info.value) and "☃" in str(info.value)
