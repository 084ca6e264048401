"""``knotmm sweep --set/--duration``: applied to every point, recorded, and held to on reruns.

The points are tiny (30 and 36 beads, no knot-type checks, no plots): a few seconds in all.
"""

from __future__ import annotations

import pytest

from knotmm.cli.main import main
from knotmm.config import read_toml
from knotmm.sweep import read_summary

SWEEP_TOML = """
[knot]
beads = 30

[run]
duration = 40.0
topology_check_interval = 0.0

[output]
frame_interval = 0.5
directory = "{directory}"

[sweep]
"knot.beads" = [30, 36]
knot_samples = 0
plots = false
"""


@pytest.fixture(scope="module")
def shortened(tmp_path_factory):
    """A sweep of two 40 tau_d points run as 9 tau_d ones with --duration and --set."""
    base = tmp_path_factory.mktemp("sweep_set")
    path = base / "sweep.toml"
    path.write_text(SWEEP_TOML.format(directory=(base / "out").as_posix()))
    code = main(["sweep", str(path), "--workers", "0", "--no-progress", "--duration", "9",
                 "--set", "run.max_bond_length=2.5"])
    assert code == 0
    return path, base / "out"


def test_every_point_runs_with_the_set_keys_and_records_them(shortened):
    _, out = shortened
    for name in ("knot.beads=30", "knot.beads=36"):
        run = read_toml(out / name / "run.toml")
        assert run["run"]["duration"] == 9.0
        assert run["run"]["max_bond_length"] == 2.5
    rows = read_summary(out / "summary.csv")
    assert [r["status"] for r in rows] == ["finished", "finished"]
    # the runs stopped at the set duration, not the file's 40 tau_d
    assert all(abs(float(r["time_reached"]) - 9.0) < 1e-6 for r in rows)
    recorded = read_toml(out / "sweep.toml")
    assert recorded["run"]["duration"] == 9.0
    assert recorded["sweep"]["set"] == {"run.duration": 9.0, "run.max_bond_length": 2.5}


def test_rerun_with_the_same_set_skips_finished_points(shortened, capsys):
    path, _ = shortened
    capsys.readouterr()
    assert main(["sweep", str(path), "--workers", "0", "--no-progress", "--duration", "9",
                 "--set", "run.max_bond_length=2.5"]) == 0
    assert "2 already finished" in capsys.readouterr().out


def test_the_recorded_sweep_file_continues_the_sweep(shortened, capsys):
    _, out = shortened
    capsys.readouterr()
    assert main(["sweep", str(out / "sweep.toml"), "--workers", "0", "--no-progress"]) == 0
    assert "2 already finished" in capsys.readouterr().out


@pytest.mark.parametrize("extra", [[], ["--duration", "10"],
                                   ["--duration", "9", "--set", "run.max_bond_length=2.5",
                                    "--set", "run.seed=4"]])
def test_rerun_with_other_set_keys_is_refused_in_one_line(shortened, capsys, extra):
    path, out = shortened
    before = (out / "summary.csv").read_text()
    capsys.readouterr()
    assert main(["sweep", str(path), "--workers", "0", "--no-progress", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert err.startswith("knotmm: error: sweep refused:")
    started = err.split("was started with ")[1].split(" (its sweep.toml)")[0]
    assert sorted(started.split(" --set ")) == ["--set run.max_bond_length=2.5",
                                                 "run.duration=9.0"]
    assert (out / "summary.csv").read_text() == before  # nothing was run or rewritten


@pytest.mark.parametrize("flags, key", [
    (["--set", "knot.beads=40"], "knot.beads"),
    (["--duration", "9"], "run.duration"),
])
def test_a_swept_key_cannot_be_set(tmp_path, capsys, flags, key):
    path = tmp_path / "s.toml"
    text = SWEEP_TOML.format(directory=(tmp_path / "out").as_posix())
    if key == "run.duration":
        text = text.replace('"knot.beads" = [30, 36]', '"run.duration" = [3.0, 4.0]')
    path.write_text(text)
    assert main(["sweep", str(path), "--dry-run", *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert f"the sweep varies {key}" in err
    assert not (tmp_path / "out").exists()


def test_set_of_the_seed_of_an_ensemble_is_refused(tmp_path, capsys):
    path = tmp_path / "s.toml"
    text = SWEEP_TOML.format(directory=(tmp_path / "out").as_posix())
    path.write_text(text.replace('"knot.beads" = [30, 36]', "seeds = 2"))
    assert main(["sweep", str(path), "--dry-run", "--set", "run.seed=3"]) == 2
    assert "the sweep varies run.seed (seeds = K" in capsys.readouterr().err


def test_unknown_set_key_is_one_line(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP_TOML.format(directory=(tmp_path / "out").as_posix()))
    assert main(["sweep", str(path), "--dry-run", "--set", "run.durration=3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "run.durration" in err


def test_dry_run_lists_the_set_keys(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP_TOML.format(directory=(tmp_path / "out").as_posix()))
    assert main(["sweep", str(path), "--dry-run", "--duration", "2"]) == 0
    assert "every point with --set run.duration=2.0" in capsys.readouterr().out
