"""What ``knotmm run`` says about the plugin: one line when it cannot be used as built.

A plugin built against another OpenMM than the one imported is named on every run, whatever
``run.engine`` says, with the command that rebuilds it; ``KNOTMM_NO_PLUGIN=1`` is the user's
choice: silent with ``run.engine = "auto"``, one line saying so with ``"plugin"``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import openmm.version
import pytest

import knotmm.plugin
from knotmm.io.rundir import read_facts

#: A running OpenMM the build cannot match (the brief's 8.7.0, unless that is the real one).
FAKE = "8.7.0" if openmm.version.version.split(".")[:2] != ["8", "7"] else "9.9.0"

_RUN = textwrap.dedent("""
    import sys
    import openmm.version
    if sys.argv[1]:
        openmm.version.version = sys.argv[1]  # as if OpenMM was upgraded after the build
    from knotmm.cli.main import main
    sys.exit(main(sys.argv[2:]))
    """)


def _knotmm(args, fake_version="", **env):
    environ = {k: v for k, v in os.environ.items() if k != "KNOTMM_NO_PLUGIN"} | env
    proc = subprocess.run([sys.executable, "-c", _RUN, fake_version, *args],
                          capture_output=True, text=True, timeout=300, env=environ)
    assert proc.returncode == 0, proc.stderr
    return proc.stderr.splitlines()


def _knotmm_run(tmp_path, engine, fake_version="", **env):
    out = tmp_path / f"run_{engine}"
    lines = _knotmm(["run", "--duration", "1", "--beads", "40", "--set", f"run.engine={engine}",
                     "--set", "run.topology_check_interval=0", "--no-progress", "--out",
                     str(out)], fake_version, **env)
    return lines, read_facts(out)["engine"]


@pytest.mark.skipif(not knotmm.plugin.available(), reason="needs a built plugin to mismatch")
@pytest.mark.parametrize("engine", ["auto", "plugin", "python"])
def test_a_plugin_built_for_another_openmm_is_named_on_every_run(tmp_path, engine):
    lines, recorded = _knotmm_run(tmp_path, engine, FAKE)
    assert len(lines) == 1, lines
    line = lines[0]
    assert line.startswith("knotmm: ")
    assert f"but OpenMM {FAKE} is installed" in line
    assert knotmm.plugin.REBUILD_COMMAND in line and "using the Python engine" in line
    assert recorded == "python"


@pytest.mark.skipif(not knotmm.plugin.available(), reason="needs a built plugin to mismatch")
def test_a_resumed_run_names_it_too(tmp_path):
    lines, _ = _knotmm_run(tmp_path, "python")
    assert lines == []
    lines = _knotmm(["run", "--resume", str(tmp_path / "run_python"), "--duration", "2",
                     "--no-progress"], FAKE)
    assert len(lines) == 1, lines
    assert f"but OpenMM {FAKE} is installed" in lines[0]
    assert lines[0].endswith("the run goes on with the python engine it was made with")


@pytest.mark.parametrize(("engine", "says"), [("auto", False), ("plugin", True),
                                              ("python", False)])
def test_knotmm_no_plugin_is_the_users_choice(tmp_path, engine, says):
    lines, recorded = _knotmm_run(tmp_path, engine, KNOTMM_NO_PLUGIN="1")
    assert recorded == "python"
    if not says:
        assert lines == []
        return
    assert len(lines) == 1, lines
    assert "switched off by the environment variable KNOTMM_NO_PLUGIN=1" in lines[0]
    assert "could not be loaded" not in lines[0] and "Build it" not in lines[0]
    assert lines[0].startswith('knotmm: run.engine = "plugin": ')
