"""The small things a user expects of the command line and the API (issue 35).

``python -m knotmm``; ``knotmm analyse``; a did-you-mean for an unknown command;
``knotmm --version`` as OpenMM's ``testInstallation``; ``dir(knotmm)``; a replica set's
directory given where one run is expected; links in ``knotmm template --list`` and a hint for
a LinkInfo name without its orientation; the note of a run without topoly.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import knotmm
from knotmm.cli.main import ALIASES, COMMANDS, main
from knotmm.errors import TrajectoryFileError


def _python(*argv, cwd, timeout=120):
    """A fresh interpreter (real stdout, stderr and logging), pytest's variables left out."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    return subprocess.run([sys.executable, *argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def _error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("knotmm: error:")]


def test_python_m_knotmm_is_the_knotmm_command(tmp_path):
    done = _python("-m", "knotmm", "--version", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"knotmm {knotmm.__version__} ")


def test_version_reports_openmm_the_plugin_and_the_platforms(capsys):
    import openmm

    from knotmm import plugin

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith(f"knotmm {knotmm.__version__} (Python ")
    assert lines[1] == f"OpenMM {openmm.version.full_version}"
    state = next(line for line in lines if line.startswith("plugin: "))
    if plugin.available():
        assert state.startswith("plugin: loaded (RPYIntegrator: ") and "rk23" in state
    else:
        assert state.startswith("plugin: not loaded (")
    platforms = next(line for line in lines if line.startswith("platforms: "))
    assert "Reference" in platforms.split(": ", 1)[1].split(", ")


def test_version_says_why_the_plugin_did_not_load(monkeypatch, capsys):
    from knotmm import plugin

    monkeypatch.setattr(plugin, "available", lambda: False)
    monkeypatch.setattr(plugin, "load_error", lambda: "knotmm.plugin: not built here")
    with pytest.raises(SystemExit):
        main(["--version"])
    out = capsys.readouterr().out
    assert "plugin: not loaded (not built here); runs use the Python engine" in out


def test_analyse_is_analyze(tmp_path, capsys):
    missing = tmp_path / "no_such_run"
    assert main(["analyse", str(missing)]) == 2  # analyze's own error, not argparse's
    err = capsys.readouterr().err
    assert _error_lines(err) == [f"knotmm: error: {missing}: no such run directory or "
                                 f"trajectory file; give a run directory (with "
                                 f"trajectory.dcd, topology.pdb, run.toml) or a DCD file"]
    assert ALIASES == {"analyse": "analyze"}


@pytest.mark.parametrize(("typed", "meant"), [("anlyze", "'analyze'"), ("analyis", "'analyze'"),
                                              ("movi", "'movie'"), ("templte", "'template'")])
def test_an_unknown_command_gets_a_did_you_mean(typed, meant, capsys):
    with pytest.raises(SystemExit) as info:
        main([typed, "x"])
    assert info.value.code == 2
    (line,) = _error_lines(capsys.readouterr().err)
    assert line == (f"knotmm: error: unknown command {typed!r}: did you mean {meant}? the "
                    f"commands are {', '.join(COMMANDS)} (knotmm COMMAND -h for one)")


def test_an_unknown_command_far_from_any_gets_the_list(capsys):
    with pytest.raises(SystemExit):
        main(["frobnicate"])
    (line,) = _error_lines(capsys.readouterr().err)
    assert "did you mean" not in line and "the commands are run, template" in line


def test_dir_of_knotmm_shows_the_public_api_only():
    public = ["RunConfig", "Simulation", "__version__", "analyze_run", "build_system",
              "load_run", "resume", "run"]
    assert dir(knotmm) == public
    for helper in ("version", "PackageNotFoundError", "import_module"):
        assert not hasattr(knotmm, helper)
    for name in public:
        assert getattr(knotmm, name) is not None
    assert knotmm.Simulation.__module__ == "knotmm.engine.simulation"


@pytest.fixture
def replica_set(tmp_path):
    """A replica set's directory: replicas.toml and three (empty) replica directories."""
    from knotmm.io.replica_set import write_replica_set

    root = tmp_path / "set"
    root.mkdir()
    write_replica_set(root, {"replicas": {"count": 3, "seeds": [1, 2, 3]},
                             "run_file": {"run": {"replicas": 3}}})
    for k in range(3):
        (root / f"replica_{k}").mkdir()
    return root


def _replica_set_line(root) -> str:
    return (f"{root}: this is a replica set of 3 replicas (replicas.toml), not one run: give "
            f"one of them, {root / 'replica_K'} with K = 0 ... 2")


def test_simulation_and_sweep_reprs_say_what_they_are_in_one_short_line(tmp_path):
    from knotmm import Simulation
    from knotmm.shapes import torus_knot
    from knotmm.sweep.runner import SweepResult
    from knotmm.sweep.spec import Sweep

    sim = Simulation(torus_knot(2, 3, 40), platform="Reference")
    sim.run(0.1)
    text = repr(sim)
    assert text.startswith("Simulation(40 beads, one ring, t = 0.1 tau_d, step ")
    assert "rk23 on the python engine, Reference" in text
    sweep = Sweep.from_dict({"knot": {"beads": 40}, "run": {"duration": 1.0},
                             "sweep": {"seeds": 2, "knot.beads": [40, 50, 60]}},
                            directory=tmp_path / "s")
    text = repr(sweep)
    assert text.startswith("Sweep(6 points: knot.beads x3, seeds=2, mode='grid'")
    assert "\n" not in text and len(text) < 200  # was about 10 kB
    result = SweepResult(tmp_path, [{"status": "finished"}, {"status": "fault"}],
                         tmp_path / "summary.csv", [], 1, 0, 1, 0, 3.0)
    assert repr(result).startswith("SweepResult(2 points, 1 not finished, ran=1")


def test_load_run_of_a_replica_set_names_its_replicas(replica_set):
    with pytest.raises(TrajectoryFileError) as info:
        knotmm.load_run(replica_set)
    assert str(info.value) == _replica_set_line(replica_set)


def test_a_damaged_replica_set_record_still_gets_the_replica_line(replica_set):
    (replica_set / "replicas.toml").write_text("not toml [")
    with pytest.raises(TrajectoryFileError, match="replica set of 3 replicas"):
        knotmm.load_run(replica_set)


@pytest.mark.parametrize("command", ["movie", "orbit"])
def test_movie_and_orbit_of_a_replica_set_name_its_replicas(command, replica_set, capsys):
    assert main([command, str(replica_set)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [f"knotmm: error: {_replica_set_line(replica_set)}"]
    assert sorted(p.name for p in replica_set.iterdir()) == [
        "replica_0", "replica_1", "replica_2", "replicas.toml"]


def test_template_list_lists_the_links(capsys):
    from knotmm.shapes.links import COMMON_LINKS

    assert main(["template", "--list"]) == 0
    out = capsys.readouterr().out
    assert "links (several closed chains" in out
    for name in COMMON_LINKS:
        assert f"\n  {name} " in out
    assert "L4a1{1}" in out and "orientation in braces" in out


@pytest.mark.parametrize("name", ["L6a4{0}", "L6a4"])
def test_a_linkinfo_name_without_its_orientation_gets_a_hint(name, capsys):
    pytest.importorskip("database_knotinfo")
    assert main(["template", name, "--beads", "120"]) == 2
    (line,) = _error_lines(capsys.readouterr().err)
    assert line == (f"knotmm: error: knot.name={name!r} is not in the LinkInfo tables (L6a4 is "
                    f"there as L6a4{{0,0}}, L6a4{{1,0}}, L6a4{{0,1}}, L6a4{{1,1}}: the braces "
                    f"give the orientation, one 0 or 1 per component after the first)")


def test_a_run_without_topoly_says_so_once_at_normal_verbosity(tmp_path):
    (tmp_path / "run.toml").write_text(textwrap.dedent("""\
        [knot]
        kind = "torus"
        p = 2
        q = 3
        beads = 30
        [run]
        duration = 1.0
        replicas = 2
        peclet = 10.0
        [output]
        directory = "set"
        frame_interval = 1.0
        """))
    script = ("import knotmm.knots.identify as i; i.topoly_available = lambda: False; "
              "from knotmm.cli.main import main; raise SystemExit(main(['run', 'run.toml', "
              "'--no-progress']))")
    done = _python("-c", script, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr
    notes = [line for line in done.stderr.splitlines() if line.startswith("knotmm: note:")]
    assert notes == ["knotmm: note: knot type not checked (neither the template's nor along "
                     "the run): topoly is not installed, and strands can pass one another in "
                     "the model, so the knot type may change unseen; pip install "
                     "'knotmm[knots]' checks it (or set run.topology_check_interval = 0 to "
                     "run unchecked)"]
    from knotmm.io.rundir import read_facts

    facts = read_facts(tmp_path / "set" / "replica_1")
    assert facts["knot_type_watch"] == "not made: topoly is not installed"


def test_version_into_a_pipe_closed_early_is_no_traceback():
    """``knotmm --version | head -1``: the reader closes the pipe after one line; the
    report's other lines must not end in a BrokenPipeError traceback."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "knotmm", "--version"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before anything was written
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    proc.stderr.close()
    assert "Traceback" not in err and "BrokenPipe" not in err, err


def test_the_version_has_one_owner_that_the_installed_metadata_and_citation_follow():
    """``knotmm/__init__.py`` holds the version; the build reads it from there (pyproject's
    regex provider), and CITATION.cff states it too."""
    from importlib.metadata import version

    root = Path(knotmm.__file__).resolve().parent.parent
    assert version("knotmm") == knotmm.__version__
    pyproject = (root / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in pyproject and "\nversion =" not in pyproject
    citation = (root / "CITATION.cff").read_text()
    assert f"\nversion: {knotmm.__version__}\n" in citation
