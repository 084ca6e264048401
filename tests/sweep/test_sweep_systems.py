"""Sweeps of several chains (``[[chains]]``) and of open filaments (issue 30, BUG-7, BUG-12).

* a sweep of ``[[chains]]`` points is continued (the finished points skipped, a killed point
  resumed) and its stored run files are compared table by table and chain by chain;
* ``knotmm sweep --dry-run`` checks each point on the system the run builds (its chains, its
  open ends), not on one ring through every bead.

The runs are tiny: two 30-bead rings, 4 tau_d, no knot-type checks, no plots.
"""

from __future__ import annotations

import pytest

from knotmm.cli.main import main
from knotmm.config import read_toml
from knotmm.sweep import Sweep, check_points, run_point, run_sweep
from knotmm.sweep.plan import plan_point

# cfg/sw_chains.toml of the audit, shortened: a trefoil and a Hopf link side by side
CHAINS_TOML = """\
[[chains]]
beads = 30
offset = [-4.0, 0.0, 0.0]
[[chains]]
kind = "knotinfo"
name = "hopf"
beads = 40
offset = [5.0, 0.0, 0.0]
[run]
duration = 4.0
peclet = 10.0
[output]
frame_interval = 0.25
[sweep]
"model.bending_stiffness" = [3.0, 6.0]
seeds = 2
knot_samples = 0
plots = false
"""

# cfg/sw_open.toml of the audit: an open helix
OPEN_TOML = """\
[knot]
kind = "helix"
beads = 30
[run]
duration = 4.0
[output]
frame_interval = 0.25
[sweep]
"model.bending_stiffness" = [3.0, 6.0]
knot_samples = 0
plots = false
"""


def chains_sweep(directory, offsets=(-4.0, 4.0), beads=30) -> Sweep:
    """Two trefoil rings side by side, one swept point; 4 tau_d at Pe 10."""
    chains = [{"beads": beads, "offset": [x, 0.0, 0.0]} for x in offsets]
    return Sweep.from_dict({
        "chains": chains,
        # no knot-type checks during the runs: these tests are about the sweep machinery
        "run": {"duration": 4.0, "peclet": 10.0, "topology_check_interval": 0.0},
        "output": {"directory": str(directory), "frame_interval": 0.25},
        "sweep": {"model.bending_stiffness": [3.0], "knot_samples": 0, "plots": False},
    })


# -- BUG-7: continuing a sweep of [[chains]] points --------------------------------------------
@pytest.fixture(scope="module")
def finished_chains(tmp_path_factory):
    directory = tmp_path_factory.mktemp("chains") / "sweep"
    sweep = chains_sweep(directory)
    result = run_sweep(sweep, workers=0, progress=False)
    assert [r["status"] for r in result.rows] == ["finished"], result.report()
    return sweep, result


def test_a_finished_chains_sweep_is_continued_without_running_again(finished_chains):
    sweep, first = finished_chains
    point_dir = first.directory / sweep.points[0].name
    stamp = (point_dir / "trajectory.dcd").stat().st_mtime_ns
    again = run_sweep(sweep, workers=0, progress=False)  # the same command again
    assert (again.ran, again.resumed, again.analysed, again.skipped) == (0, 0, 0, 1)
    assert (point_dir / "trajectory.dcd").stat().st_mtime_ns == stamp
    assert again.rows == first.rows


def test_a_killed_chains_point_is_resumed(finished_chains, tmp_path):
    import shutil

    sweep, first = finished_chains
    directory = tmp_path / "killed"
    shutil.copytree(first.directory, directory)
    moved = Sweep.from_dict({**sweep.data, "output": {**sweep.data["output"],
                                                      "directory": str(directory)}})
    # a sweep killed while simulating leaves its point's run.toml saying "running"
    toml = directory / moved.points[0].name / "run.toml"
    toml.write_text(toml.read_text().replace('status = "finished"', 'status = "running"'))
    result = run_sweep(moved, workers=0, progress=False)
    assert (result.ran, result.resumed, result.analysed, result.skipped) == (0, 1, 0, 0)
    assert [r["status"] for r in result.rows] == ["finished"]
    assert read_toml(toml)["knotmm"]["status"] == "finished"


@pytest.mark.parametrize(
    ("offsets", "beads", "why"),
    [((-4.0, 5.0), 30, "a chain moved"), ((-4.0, 4.0, 12.0), 30, "a chain added"),
     ((-4.0, 4.0), 32, "chains of other lengths")],
)
def test_changed_chains_are_run_again(finished_chains, offsets, beads, why):
    sweep, first = finished_chains
    point_dir = first.directory / sweep.points[0].name
    assert plan_point(sweep.points[0], point_dir, False)[0] == "skip"
    changed = chains_sweep(first.directory, offsets, beads).points[0]
    assert plan_point(changed, point_dir, False)[0] == "run", why


# -- BUG-12: --dry-run builds each point's system as the run does -----------------------------
@pytest.mark.parametrize("text", [CHAINS_TOML, OPEN_TOML], ids=["chains", "open_helix"])
def test_dry_run_accepts_what_the_run_runs(tmp_path, capsys, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    out = tmp_path / "o"
    assert main(["sweep", str(path), "--dry-run", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "pass the checks" in captured.out and "cannot run" not in captured.out
    assert "error" not in captured.err
    assert not out.exists()


def test_dry_run_refuses_what_the_run_refuses_for_chains(tmp_path):
    """Two chains on top of each other: the dry run names the run's own reason, per point."""
    sweep = chains_sweep(tmp_path / "o", offsets=(0.0, 0.5))
    (check,) = check_points(sweep.points)
    point = sweep.points[0]
    ran = run_point({"name": point.name, "directory": str(tmp_path / "run"),
                     "config": point.config.to_dict(), "action": "run"})
    assert ran["status"] == "error"
    assert check.error is not None and ran["error"].endswith(check.error)
    assert not (tmp_path / "run").exists()
