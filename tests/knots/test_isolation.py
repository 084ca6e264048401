"""topoly stays out of knotmm's processes, and scripts without a main guard run once.

Regression tests of issue 11, items 1 and 6: the knot worker is started as its own module
(never by re-running the user's ``__main__``), run.toml counts only checks that ran, and
neither ``knotmm.run`` nor ``knotmm.analyze_run`` imports topoly in the calling process.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from knotmm.knots.identify import topoly_available

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")

SHORT_RUN = {
    "knot": {"beads": 40},
    "run": {"duration": 2.0, "topology_check_interval": 0.5},
    "output": {"frame_interval": 0.1},
}


def test_importing_the_workflow_does_not_import_topoly():
    code = "import knotmm.workflow, knotmm.analysis.core"
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "topoly" not in done.stderr


@needs_topoly
def test_an_unguarded_script_with_knot_checks_leaves_a_consistent_run(tmp_path):
    """The README's snippet as a script without ``if __name__ == "__main__":``, with
    ``overwrite=True`` (a worker that re-ran the script would wipe the directory under the
    run): every frame recorded is in the DCD, the checks counted ran, nothing on stderr."""
    script = tmp_path / "snippet.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import sys
            import time
            import knotmm
            from knotmm.knots.identify import start_worker, worker_ready

            print("body", flush=True)
            start_worker()
            while not worker_ready():  # a run's end does not wait for topoly's import
                time.sleep(0.05)
            cfg = knotmm.RunConfig.from_dict({SHORT_RUN!r})
            knotmm.run(cfg, "out", overwrite=True, progress=False)
            print("topoly" in sys.modules, flush=True)
            """
        )
    )
    from knotmm.config import read_toml
    from knotmm.io.dcd import dcd_layout

    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["body", "False"]  # the body ran once; no topoly here
    assert "Traceback" not in done.stderr and "Error" not in done.stderr, done.stderr
    facts = read_toml(tmp_path / "out" / "run.toml")["knotmm"]
    layout = dcd_layout(tmp_path / "out" / "trajectory.dcd")
    assert facts["status"] == "finished"
    assert facts["frames"] == layout.claimed_frames == layout.complete_frames == 21
    assert facts["knot_type_checks"] == 4  # t = 0.5, 1, 1.5, 2: all of them ran
    assert facts["knot_type_start"] == facts["knot_type"] == "+3_1"


@needs_topoly
def test_run_and_analysis_never_import_topoly_here(tmp_path):
    import knotmm

    cfg = knotmm.RunConfig.from_dict(SHORT_RUN)
    result = knotmm.run(cfg, tmp_path / "run", progress=False)
    assert result.frames == 21
    assert "topoly" not in sys.modules
    analysis = knotmm.analyze_run(tmp_path / "run", plots=False, knot_samples=4)
    assert analysis.knots.initial == "+3_1"
    assert "topoly" not in sys.modules


class _Sim:
    time, currentStep = 1.0, 100
    positions = None


def test_run_toml_counts_only_the_checks_that_ran():
    """A check whose worker crashed or timed out (None) is skipped, not counted."""
    from knotmm.engine.reporters import KnotTypeWatch

    answers = iter([None, "+3_1", None, "unknown"])
    watch = KnotTypeWatch(1.0, expected="+3_1", identify=lambda x: next(answers))
    for _ in range(4):
        watch.report(_Sim(), None)
    assert (watch.checks, watch.skipped, watch.changes) == (2, 2, [])
