"""Issue 30: a single run that stopped before its first checkpoint (a disk that filled up, a
kill in its first frames) is finished by ``knotmm run --resume``, from its start, as a
replica of a set is; it was refused for good ("start it again with --overwrite")."""

from __future__ import annotations

import mdtraj
import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.io.rundir import CHECKPOINT_FILE, RUN_FILE, read_facts, write_run_toml
from knotmm.workflow import run

#: Two chains, Brownian: a system of several chains, not one ring.
RUN = {
    "chains": [{"beads": 30, "offset": [-4.0, 0.0, 0.0]},
               {"kind": "arc", "beads": 20, "offset": [4.0, 0.0, 0.0]}],
    "run": {"duration": 0.3, "peclet": 5.0, "seed": 11, "topology_check_interval": 0.0},
    "output": {"frame_interval": 0.05, "checkpoint_interval": 0.1},
}


def _xyz(directory):
    return mdtraj.load_dcd(str(directory / "trajectory.dcd"),
                           top=str(directory / "topology.pdb")).xyz


@pytest.mark.parametrize("status", ["running", "fault", "interrupted"])
def test_resume_of_a_run_with_no_checkpoint_runs_it_from_its_start(tmp_path, capsys, status):
    cfg = RunConfig.from_dict(RUN)
    reference = tmp_path / "reference"
    run(cfg, reference, progress=False)
    stopped = tmp_path / "stopped"
    run(cfg, stopped, progress=False)
    # what a disk full before the first checkpoint, or a kill, leaves behind
    (stopped / CHECKPOINT_FILE).unlink()
    facts = read_facts(stopped)
    facts.update(status=status, time_reached=0.0)
    write_run_toml(stopped, cfg.replace({"output.directory": str(stopped)}), facts)
    assert main(["run", "--resume", str(stopped), "--no-progress"]) == 0, \
        capsys.readouterr().err
    assert read_facts(stopped)["status"] == "finished"
    np.testing.assert_array_equal(_xyz(stopped), _xyz(reference))
    assert (stopped / RUN_FILE).is_file() and (stopped / CHECKPOINT_FILE).is_file()
