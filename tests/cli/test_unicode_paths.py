"""Run directories whose path has spaces and non-ASCII characters (issue 23, item 3).

``knotmm run --out "dir with spaces/ünïcødé ☃ run"`` always worked, but every command that
reads the DCD back (``analyze``, ``orbit``, ``movie``) stopped with mdtraj's
``UnicodeEncodeError: 'ascii' codec`` (its ``DCDTrajectoryFile`` encodes a ``str`` file name
as ASCII; ``knotmm.io.dcd.c_path`` hands it the OS bytes instead). The run and two analyses
run in child processes under LANG=C.UTF-8, LANG=C and no locale at all; ``movie`` and
``orbit`` run in this process (a child's locale changes nothing more for them).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from test_run_fuzz import RUN_OPTIONS, _call, _status

#: Spaces, Latin-1 letters and a character outside Latin-1, at two levels.
ODD = os.path.join("dir with spaces", "ünïcødé ☃ run")
#: Environments without any locale variable, and with two common ones.
LOCALES = {"C.UTF-8": {"LANG": "C.UTF-8"}, "C": {"LANG": "C", "LC_ALL": "C"}, "none": {}}


def _env(extra: dict) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("LC_") and k not in ("LANG", "LANGUAGE", "PYTHONUTF8",
                                                     "PYTHONIOENCODING")}
    env.update(extra)
    return env


def _knotmm(argv, cwd, locale: str) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "knotmm.cli", *argv], cwd=cwd,
                          env=_env(LOCALES[locale]), capture_output=True, timeout=300)
    err = proc.stderr.decode("utf-8", "replace")
    assert "Traceback" not in err and "codec" not in err, f"LANG {locale}: {argv}\n{err}"
    return proc


@pytest.fixture(scope="module")
def odd_run(tmp_path_factory):
    """A finished 2 tau_d run of 30 beads written under an odd relative path."""
    base = tmp_path_factory.mktemp("odd paths")
    proc = _knotmm(["run", "--out", ODD, "--duration", "2",
                    "--set", "output.frame_interval=0.1", *RUN_OPTIONS], base, "C.UTF-8")
    assert proc.returncode == 0, proc.stderr.decode()
    assert _status(base / ODD) == "finished"
    return base


@pytest.mark.parametrize("locale", ["C", "none"])
def test_analyze_reads_a_run_in_an_odd_path_under_any_locale(odd_run, locale):
    out = f"analysis {locale} ☃"
    proc = _knotmm(["analyze", ODD, "--knot-samples", "0", "--no-plots", "--out", out],
                   odd_run, locale)
    assert proc.returncode == 0, proc.stderr.decode()
    result = json.loads((odd_run / out / "analysis.json").read_text())
    assert result["n_frames"] == 21


def test_analyze_movie_and_orbit_in_an_odd_absolute_path(odd_run, capsys):
    directory = str(odd_run / ODD)
    code, _ = _call(["analyze", directory, "--knot-samples", "0", "--no-plots"], capsys,
                    "analyze")
    assert code == 0
    code, _ = _call(["movie", directory, "--out", os.path.join(directory, "m ☃.gif"),
                     "--dpi", "30", "--stride", "4"], capsys, "movie")
    assert code == 0 and (odd_run / ODD / "m ☃.gif").stat().st_size > 0
    # a 2 tau_d run of 30 beads is shorter than two swirl periods (~4.8 tau_d): the analysis
    # of the DCD finds no swirl, and the orbit is refused (exit 2) in one line that names
    # the odd directory intact and says to run longer
    code, err = _call(["orbit", directory, "--modes", "0", "--out",
                       os.path.join(directory, "orbit ☃")], capsys, "orbit")
    assert code == 2, err
    assert f"{directory} has no periodic window" in err and "run it longer" in err, err
