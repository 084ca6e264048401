"""Issue 31's measure: the walk of a run configuration from ``workflow.run``.

A short run is traced (``tests/config_walk.py``: every call of a function of ``knotmm``
handed the ``RunConfig``). The issue's bounds: the walk climbs back up the layers at most 5
times, and after the plan it enters the configuration module at most once. Measured before
the plan's parts drove the run: 10 climbs (``dynamics/registry.integrator_from_config``
reading the run file, layer 1 calling config, layer 2) and 17 entries into ``config.py``
after the plan (the drive's ``Output.of``, the checks' keys, ``to_dict`` for run.toml and
the checkpoints, the template's deferred knot check); now 0 and 0.
"""

from __future__ import annotations

from config_walk import short_run, walk


def test_the_run_configuration_is_resolved_once(tmp_path):
    found = walk(short_run(), tmp_path / "r")
    assert found.steps, "the tracer saw nothing"
    assert found.climbs <= 5, found.climb_list
    assert found.config_entries_after_plan <= 1, found.after_plan()
    # the geometry reads its [knot] and [model] keys, never [run] (but where the typed
    # parts are made: tests/shapes/test_no_run_keys.py)
    allowed = {"TemplateSpec.of", "RunResources.of"}
    run_reads = [(m, f, key) for m, f, key in found.reads
                 if m and m.startswith("knotmm.shapes") and key.startswith("run.")
                 and f not in allowed]
    assert found.reads and not run_reads


def test_a_sweep_point_runs_from_the_plan(tmp_path, monkeypatch):
    """A sweep point (:func:`knotmm.sweep.point.run_point`, what every executor runs)
    validates its run file once and runs it from one plan: the same bounds (the point's
    analysis, which reads the saved run.toml as any analysis does, left out here)."""
    import matplotlib.pyplot  # noqa: F401 - imported before the tracer, as any test's

    import knotmm.analysis
    import knotmm.plan
    import knotmm.workflow
    from knotmm.config import RunConfig
    from knotmm.sweep.point import run_point

    class Analysis:
        def to_dict(self):
            return {}

    task = {"name": "p", "directory": str(tmp_path / "p"), "config": short_run().to_dict(),
            "action": "run"}
    monkeypatch.setattr(knotmm.analysis, "analyze_run", lambda *a, **k: Analysis())
    calls = []
    prepare, from_dict = knotmm.plan.prepare, RunConfig.from_dict.__func__
    monkeypatch.setattr(knotmm.workflow, "prepare",
                        lambda *a, **k: calls.append("prepare") or prepare(*a, **k))
    monkeypatch.setattr(RunConfig, "from_dict", classmethod(
        lambda cls, *a, **k: calls.append("from_dict") or from_dict(cls, *a, **k)))
    out = {}
    found = walk(None, None, call=lambda: out.update(run_point(task)))
    assert out["status"] == "finished", out
    assert calls == ["from_dict", "prepare"]
    assert found.climbs <= 5, found.climb_list
    assert found.config_entries_after_plan <= 1, found.after_plan()


def test_the_tracer_counts_climbs_and_entries():
    from config_walk import Walk

    w = Walk([("knotmm.workflow", "run", None, False),
              ("knotmm.config", "__getitem__", "knotmm.workflow", False),
              ("knotmm.dynamics.registry", "f", "knotmm.plan", False),
              ("knotmm.config", "__getitem__", "knotmm.dynamics.registry", False),
              ("knotmm.config", "to_dict", "knotmm.workflow", True)])
    assert (w.climbs, w.config_entries, w.config_entries_after_plan) == (1, 3, 1)
    assert w.stay_modules() == ["knotmm.workflow", "knotmm.config", "knotmm.dynamics.registry",
                                "knotmm.config"]
    assert (w.returns, w.stay_climbs) == (1, 1)
