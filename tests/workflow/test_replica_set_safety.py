"""Issue 30: replica sets and the start of a run lose nothing.

The lock is taken before a directory is touched (a refused ``--overwrite`` deletes nothing),
every check that can refuse a run passes before anything is deleted, an I/O failure while a
replica starts is an output fault (exit 3) that ``--resume`` repairs, a damaged
``replicas.toml`` is one line, and a start that fails on a full disk leaves nothing behind.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import mdtraj
import numpy as np
import pytest

import knotmm.workflow
from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.errors import ConfigError, RunDirectoryError, TemplateError
from knotmm.io.replica_set import REPLICA_SET_FILE, write_replica_set
from knotmm.io.rundir import (
    CHECKPOINT_FILE,
    LOCK_FILE,
    RUN_FILE,
    RUN_FILES,
    RunLock,
    read_facts,
    write_run_toml,
)
from knotmm.replicas import replica_seeds, resume_replicas, run_replicas

#: A small Brownian set: 30 beads, 0.3 tau_d, about a second a replica.
SET = {
    "knot": {"beads": 30, "minor_radius": 0.6},
    "run": {"duration": 0.3, "peclet": 10.0, "integrator": "ito_heun", "timestep": 0.002,
            "topology_check_interval": 0.0, "replicas": 3, "seed": 11},
    "output": {"frame_interval": 0.05, "checkpoint_interval": 0.1},
}
#: Two chains at the same place: refused by the template's overlap check.
OVERLAP = {
    "chains": [{"beads": 30, "offset": [-4.0, 0.0, 0.0]},
               {"kind": "arc", "beads": 20, "offset": [-4.0, 0.0, 0.0]}],
    "run": {"duration": 0.3, "peclet": 5.0, "seed": 11, "replicas": 2,
            "topology_check_interval": 0.0},
    "output": {"frame_interval": 0.05},
}


def _cfg(data=SET, **run):
    return RunConfig.from_dict({**data, "run": {**data["run"], **run}})


def _fake_run(directory: Path, status: str = "finished") -> dict[str, bytes]:
    """A run directory with every knotmm file (no simulation); returns the files' bytes."""
    directory.mkdir(parents=True, exist_ok=True)
    write_run_toml(directory, _cfg(replicas=1), {"status": status})
    for name in RUN_FILES:
        if name != RUN_FILE:
            (directory / name).write_bytes(f"{name} of {directory.name}".encode())
    return _contents(directory)


def _fake_set(root: Path, count: int = 3) -> dict[str, bytes]:
    """A replica set of ``count`` fake replicas; returns every file's bytes."""
    root.mkdir(parents=True, exist_ok=True)
    seeds = replica_seeds(11, count)
    write_replica_set(root, {"replicas": {"count": count, "seeds": seeds},
                             "run_file": _cfg().to_dict()})
    for k in range(count):
        _fake_run(root / f"replica_{k}")
    return _contents(root)


def _contents(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != LOCK_FILE}


def _xyz(directory: Path) -> np.ndarray:
    return mdtraj.load(str(directory / "trajectory.dcd"),
                       top=str(directory / "topology.pdb")).xyz


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    return err[0]


# -- BUG-1, BUG-2: the lock before anything is touched ---------------------------------------
def test_a_refused_overwrite_by_a_set_leaves_a_live_single_run_whole(tmp_path):
    directory = tmp_path / "single"
    before = _fake_run(directory, status="running")
    with RunLock(directory, "run"):  # the live run
        with pytest.raises(RunDirectoryError, match="in use"):
            run_replicas(_cfg(), directory=directory, overwrite=True, progress=False)
        assert _contents(directory) == before


@pytest.mark.parametrize("count", [2, 3])
def test_a_refused_overwrite_leaves_a_live_set_whole(tmp_path, count):
    root = tmp_path / "set"
    before = _fake_set(root, 3)
    with RunLock(root, "run"):  # the live set
        with pytest.raises(RunDirectoryError, match="in use"):
            run_replicas(_cfg(replicas=count), directory=root, overwrite=True,
                         progress=False)
        assert _contents(root) == before


# -- BUG-3: every refusal before anything is deleted ------------------------------------------
@pytest.mark.parametrize("bad, error", [
    (OVERLAP, TemplateError),
    ({**SET, "run": {**SET["run"], "replicas": 2, "integrator": "heun"}}, ConfigError),
])
def test_a_refused_overwrite_of_a_set_deletes_nothing(tmp_path, bad, error):
    root = tmp_path / "set"
    before = _fake_set(root, 3)
    with pytest.raises(error):
        run_replicas(RunConfig.from_dict(bad), directory=root, overwrite=True, progress=False)
    assert _contents(root) == before
    assert sorted(p.name for p in root.iterdir()) == sorted([
        REPLICA_SET_FILE, "replica_0", "replica_1", "replica_2"])


def test_a_template_refused_for_a_later_replica_is_found_before_anything_is_deleted(tmp_path):
    """A perturbed start depends on each replica's seed: with run.seed = 10 the third
    replica's beads come inside the steric range (the first two are fine)."""
    root = tmp_path / "set"
    before = _fake_set(root, 3)
    cfg = RunConfig.from_dict({**SET, "knot": {**SET["knot"], "perturbation": 0.15},
                               "run": {**SET["run"], "seed": 10}})
    with pytest.raises(TemplateError, match="knot.perturbation"):
        run_replicas(cfg, directory=root, overwrite=True, progress=False)
    assert _contents(root) == before


def test_a_refused_set_in_a_new_directory_creates_nothing(tmp_path):
    root = tmp_path / "new" / "set"
    with pytest.raises(TemplateError):
        run_replicas(RunConfig.from_dict(OVERLAP), directory=root, progress=False)
    assert not (tmp_path / "new").exists()


def test_a_replica_directory_in_the_way_is_refused_before_anything_is_deleted(tmp_path):
    root = tmp_path / "set"
    before = _fake_set(root, 2)
    (root / "replica_2").write_text("not a directory")
    before["replica_2"] = b"not a directory"
    with pytest.raises(RunDirectoryError, match="replica_2"):
        run_replicas(_cfg(), directory=root, overwrite=True, progress=False)
    assert _contents(root) == before


# -- BUG-8: an I/O failure during a set -------------------------------------------------------
def _full_disk_for(monkeypatch, name: str, times: int = 1) -> None:
    """Writing ``view.vmd`` into the directory ``name`` fails ``times`` times: no space."""
    real = knotmm.workflow.write_vmd_script
    left = [times]

    def full(directory, *args, **kwargs):
        if Path(directory).name == name and left[0] > 0:
            left[0] -= 1
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(Path(directory)))
        return real(directory, *args, **kwargs)

    monkeypatch.setattr(knotmm.workflow, "write_vmd_script", full)


@pytest.mark.parametrize("stepping", ["together", "one_after_another"])
def test_a_replica_that_cannot_start_is_an_output_fault_and_resume_runs_it(
        tmp_path, monkeypatch, capsys, stepping):
    _full_disk_for(monkeypatch, "replica_1")
    root = tmp_path / "set"
    argv = ["run", "--out", str(root), "--beads", "30", "--duration", "0.3", "--no-progress",
            "--set", "run.replicas=3", "--set", "run.topology_check_interval=0",
            "--set", "output.frame_interval=0.05", "--set", "output.checkpoint_interval=0.1",
            "--set", f"run.replica_stepping={stepping}", "--set", "run.replicas_at_once=2"]
    assert main(argv) == 3  # an output fault, not bad input
    note, line = capsys.readouterr().err.strip().splitlines()  # Pe = inf: identical replicas
    assert note.startswith("knotmm: note: run.replicas = 3") and "identical" in note, note
    assert line.startswith("knotmm: error: replica 1 ") and "stopped" in line, line
    assert "no space left" in line and f"--resume {root}" in line, line
    assert read_facts(root / "replica_0")["status"] == "finished"
    assert not (root / "replica_1").exists()  # its start left nothing
    if stepping == "together":  # one group of three: replica 2 ran beside replica 0
        assert read_facts(root / "replica_2")["status"] == "finished"
    else:  # two at a time: after replica 1's fault no further replica started
        assert not (root / "replica_2" / "run.toml").exists()
    assert main(["run", "--resume", str(root), "--no-progress"]) == 0
    for k in range(3):
        assert read_facts(root / f"replica_{k}")["status"] == "finished"


@pytest.fixture(scope="module")
def finished_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("ref") / "set"
    run_replicas(_cfg(replicas=2), directory=root, progress=False)
    return root


@pytest.mark.parametrize("damage", ["running", "fault", "empty"])
def test_resume_restarts_a_replica_that_never_got_its_first_checkpoint(
        tmp_path, finished_set, damage):
    import shutil

    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    where = root / "replica_1"
    (where / CHECKPOINT_FILE).unlink()
    if damage == "empty":  # what the in-place fallback of write_run_toml used to leave
        (where / RUN_FILE).write_bytes(b"")
    else:
        facts = read_facts(where)
        facts.update(status=damage, time_reached=0.0)
        write_run_toml(where, _cfg(replicas=1), facts)
    result = resume_replicas(root, progress=False)
    assert not result.errors and all(r is not None for r in result.results)
    assert read_facts(where)["status"] == "finished"
    np.testing.assert_array_equal(_xyz(where), _xyz(finished_set / "replica_1"))
    assert _contents(root / "replica_0") == _contents(finished_set / "replica_0")


# -- BUG-19: a damaged replicas.toml ----------------------------------------------------------
@pytest.mark.parametrize("text, what", [
    ("", "[replicas]"),
    ("[replicas]\ncount = 3\nseeds = [1, 2, 3]\n", "[run_file]"),
    ("[replicas]\ncount = 3\nseeds = 5\n[run_file]\n", "seeds = 5"),
    ("replicas = 3\n", "[replicas]"),
    ("[replicas]\ncount = 3\nseeds = [1, 2]\n[run_file]\n", "count = 3"),
    ("[replicas]\ncount = 2\nseeds = [1, -2]\n[run_file]\n", "seeds"),
])
def test_a_damaged_set_record_is_one_line(tmp_path, capsys, text, what):
    root = tmp_path / "set"
    _fake_set(root, 3)
    (root / REPLICA_SET_FILE).write_text(text)
    assert main(["run", "--resume", str(root), "--duration", "1"]) == 2
    line = _one_line(capsys)
    assert REPLICA_SET_FILE in line and what in line, line


# -- BUG-23: a start that fails on a full disk leaves nothing ---------------------------------
@pytest.mark.parametrize("existed", [False, True])
def test_a_start_that_fails_on_a_full_disk_leaves_nothing_and_runs_again(
        tmp_path, monkeypatch, capsys, existed):
    directory = tmp_path / "run"
    if existed:
        directory.mkdir()
    _full_disk_for(monkeypatch, "run")
    argv = ["run", "--beads", "30", "--duration", "0.2", "--out", str(directory),
            "--no-progress", "--set", "run.topology_check_interval=0",
            "--set", "output.frame_interval=0.1"]
    assert main(argv) == 2
    line = _one_line(capsys)
    assert "no space left" in line, line
    assert directory.exists() == existed
    if existed:
        assert list(directory.iterdir()) == []
    assert main(argv) == 0  # the same command, once there is room
    assert read_facts(directory)["status"] == "finished"
