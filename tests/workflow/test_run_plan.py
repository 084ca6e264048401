"""The run plan (issue 31): a run configuration resolved once into every decision of a run.

Counted per run: full validations of a run file (``RunConfig.from_dict``), integrators and
Simulations built. Before the plan a ``knotmm run --duration 1 --beads 40`` validated the
whole schema 5 times (6 when ``auto`` took rkc2) and built 2 integrators for 1 Simulation (3
for 2); these tests keep the counts where the plan put them.
"""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

import knotmm.dynamics.registry as registry
import knotmm.engine.simulation as simulation
from knotmm.config import RunConfig
from knotmm.errors import ConfigError
from knotmm.plan import Output, RunPlan, Stepping, TemplateSpec, make_plan, prepare
from knotmm.shapes import resources as resources_module
from knotmm.shapes.resources import RunResources


@pytest.fixture
def counts(monkeypatch):
    """Calls of ``RunConfig.from_dict``, ``registry.make`` (every integrator) and
    ``Simulation.__init__``, counted while the test runs."""
    found = collections.Counter()
    from_dict = RunConfig.from_dict.__func__

    def counted_from_dict(cls, *args, **kwargs):
        found["from_dict"] += 1
        return from_dict(cls, *args, **kwargs)

    make = registry.make

    def counted_make(*args, **kwargs):
        found["integrators"] += 1
        return make(*args, **kwargs)

    init = simulation.Simulation.__init__

    def counted_init(self, *args, **kwargs):
        found["simulations"] += 1
        init(self, *args, **kwargs)

    monkeypatch.setattr(RunConfig, "from_dict", classmethod(counted_from_dict))
    monkeypatch.setattr(registry, "make", counted_make)
    monkeypatch.setattr(simulation.Simulation, "__init__", counted_init)
    return found


def _cfg(bending=5.0, **run):
    return RunConfig.from_dict({"knot": {"beads": 40}, "model": {"bending_stiffness": bending},
                                "run": {"duration": 0.5, "topology_check_interval": 0.0, **run}})


@pytest.mark.parametrize(("bending", "integrator", "built"), [(5.0, "rk23", 1), (50.0, "rkc2", 2)])
def test_a_run_validates_nothing_again_and_builds_each_object_once(
        tmp_path, counts, bending, integrator, built):
    """One stiffness probe on the Simulation, which is kept whichever integrator ``auto``
    takes; one more integrator is built when it takes rkc2 (taken in place)."""
    from knotmm.config import load_run_file
    from knotmm.workflow import run

    cfg = _cfg(bending)
    counts.clear()
    run(cfg, tmp_path / "r", progress=False)
    assert counts["from_dict"] == 0  # was 3 (4 with rkc2): every replace validated it all
    assert counts["integrators"] == built  # was 2 (3)
    assert counts["simulations"] == 1  # was 2 with rkc2 until the integrator switched in place
    assert load_run_file(tmp_path / "r" / "run.toml")["run.integrator"] == integrator


def test_knotmm_run_validates_its_run_file_once(tmp_path, counts, capsys):
    """``knotmm run --duration 1 --beads 40``: the defaults validated once; the overrides,
    the plan's resolved keys and the directory only as changed keys."""
    from knotmm.cli.main import main

    assert main(["run", "--duration", "1", "--beads", "40", "--out", str(tmp_path / "r"),
                 "--no-progress"]) == 0
    assert counts["from_dict"] == 1  # was 5


def test_replace_validates_the_changed_keys_as_a_run_file_would(counts):
    cfg = RunConfig.from_dict({})
    counts.clear()
    for change in ({"run.duration": -1.0}, {"knot.beads": 3}, {"run.integrator": "rk4"},
                   {"run.min_timestep": 2.0}, {"output.frame_interval": 1e9}):
        (dotted, value), = change.items()
        table, key = dotted.split(".")
        with pytest.raises(ConfigError) as direct:
            RunConfig.from_dict({table: {key: value}})
        with pytest.raises(ConfigError) as replaced:
            cfg.replace(change)
        assert str(replaced.value) == str(direct.value)
    changes = {"run.seed": 7, "knot.kind": "braid", "knot.word": (1, -2, 1, -2),
               "run.platform": "reference", "output.frame_interval": 2}
    counts.clear()
    fast = cfg.replace(changes)
    assert counts["from_dict"] == 0
    data = cfg.to_dict()
    for dotted, value in changes.items():
        table, key = dotted.split(".")
        data[table][key] = value
    assert fast == RunConfig.from_dict(data)
    assert fast["run.platform"] == "Reference" and fast["knot.word"] == [1, -2, 1, -2]
    with pytest.raises(ConfigError, match="either"):  # a change of shape, as a run file
        cfg.replace({"chains": [{"beads": 40}]})


def test_chain_config_is_the_entry_as_a_knot_table_without_validating_again(counts):
    cfg = RunConfig.from_dict({"chains": [{"beads": 40, "offset": [0, 0, 0]},
                                          {"kind": "braid", "word": [1, 1, 1], "beads": 50,
                                           "offset": [0, 0, 8], "perturbation": 0.01}]})
    counts.clear()
    sub = cfg.chain_config(1)
    assert counts["from_dict"] == 0
    data = cfg.to_dict()
    entry = {k: v for k, v in data.pop("chains")[1].items() if k not in ("offset", "rotation")}
    assert sub == RunConfig.from_dict({**data, "knot": entry})
    assert sub.replace({"knot.seed": 3})["knot.seed"] == 3


#: ito_heun_adaptive's default tolerance at Pe = 2: 0.02 (10 / Pe)^0.5 d.
TOLERANCE_AT_PE_2 = 0.02 * 5**0.5


def test_the_plan_holds_every_decision():
    plan = make_plan(_cfg(2.0, peclet=2.0, platform="Reference", seed=11))
    assert isinstance(plan, RunPlan)
    assert plan.stepping == Stepping(
        integrator="ito_heun_adaptive", timestep=0.002, tolerance=TOLERANCE_AT_PE_2,
        max_timestep=1.0,
        min_timestep=1e-7, peclet=2.0, kT=0.5, seed=11, noise="auto",
        noise_method="cholesky", lanczos_tolerance=plan.config["run.lanczos_tolerance"])
    assert plan.config["run.integrator"] == "ito_heun_adaptive"
    assert plan.config["run.tolerance"] == TOLERANCE_AT_PE_2
    assert plan.config["knot.major_radius"] > 0
    assert plan.reasons["integrator_choice"].startswith("auto at run.peclet = 2:")
    assert plan.placement.platform == "Reference" and plan.placement.precision == "double"
    assert plan.resources == RunResources(brownian=True, noise="auto",
                                          engine=plan.placement.engine)
    assert plan.n_beads == 40 and plan.model.bending_stiffness == 2.0
    assert plan.template.kind == "torus" and plan.template.seeds == (None,)
    assert plan.template.max_bond_length == 3.0
    assert plan.duration == 0.5 and plan.checks.interval == 0.0
    assert plan.record == plan.config.to_dict()
    with pytest.raises(AttributeError):
        plan.n_beads = 41  # frozen


def test_cpu_forces_are_single_precision_as_openmm_says():
    import openmm

    if "CPU" not in [openmm.Platform.getPlatform(i).getName()
                     for i in range(openmm.Platform.getNumPlatforms())]:
        pytest.skip("no CPU platform")
    plan = make_plan(_cfg(platform="CPU"))
    assert (plan.placement.platform, plan.placement.precision) == ("CPU", "single")


@pytest.mark.parametrize(("platform", "precision"), [("CPU", "single"), ("Reference", "double")])
def test_the_plan_records_the_noise_factors_precision(platform, precision):
    """Cholesky noise on the plugin engine: the factor's precision follows the platform's
    forces, and the plan says so (``run.toml``); no noise, nothing said."""
    pytest.importorskip("knotmm.plugin._rpyplugin")
    plan = make_plan(_cfg(peclet=2.0, platform=platform, engine="plugin"))
    assert plan.reasons["noise_precision"].startswith(f"{precision}: ")
    assert f"{platform} platform's forces" in plan.reasons["noise_precision"]
    assert "noise_precision" not in make_plan(_cfg(platform=platform, engine="plugin")).reasons


def test_the_perturbation_seed_rule_is_the_builders():
    """The spec's seeds are the ones the template builder used (knot.seed, else run.seed;
    run.seed + index for [[chains]] entries)."""
    knot = RunConfig.from_dict({"knot": {"beads": 60, "perturbation": 0.01},
                                "run": {"seed": 5, "duration": 1.0}})
    built = prepare(knot, identify="skip")
    assert built.plan.template.seeds == (built.template.resolved["knot.seed"],) == (5,)
    chains = RunConfig.from_dict({"run": {"seed": 5, "duration": 1.0}, "chains": [
        {"beads": 60, "perturbation": 0.01},
        {"beads": 60, "offset": [0, 0, 8], "perturbation": 0.01, "seed": 2},
        {"beads": 60, "offset": [0, 0, 16]}]})
    built = prepare(chains, identify="skip")
    assert built.plan.template.seeds == (5, 2, None)
    assert [e.get("seed") for e in built.template.resolved["chains"]] == [5, 2, None]
    assert TemplateSpec.of(chains).perturbation == 0.01


def test_output_intervals():
    out = Output.of(RunConfig.from_dict({"output": {"frame_interval": 0.3,
                                                    "checkpoint_interval": 1.0}}))
    assert out.observables_interval == 0.3
    assert math.isclose(out.checkpoint_interval, 1.2)  # a whole number of frames


def test_the_geometry_takes_the_memory_budget_as_values(monkeypatch):
    """build_template checks the chain against the budget it is given, not the run file's
    [run] table: a deterministic run file with a dense-noise budget is refused."""
    from knotmm.shapes.builder import build_template

    monkeypatch.setattr(resources_module, "available_memory", lambda: 1_000_000)
    cfg = RunConfig.from_dict({"knot": {"beads": 200}})  # deterministic: no noise
    build_template(cfg, identify="skip")
    with pytest.raises(ConfigError, match=r"knot\.beads=200 with run\.noise = 'cholesky'"):
        build_template(cfg, identify="skip", resources=RunResources(True, "cholesky"))
    assert RunResources.of(cfg) == RunResources(False, "auto")
    assert RunResources(True, "auto").noise_method(400) == "lanczos"


@pytest.fixture
def contexts(monkeypatch):
    """``openmm.Context``s made while the test runs (the run's and any probe's)."""
    import openmm

    made = []
    init = openmm.Context.__init__

    def counted(self, *args, **kwargs):
        made.append(1)
        init(self, *args, **kwargs)

    monkeypatch.setattr(openmm.Context, "__init__", counted)
    return made


@pytest.mark.parametrize(("engine", "bending", "integrator", "made"), [
    ("python", 5.0, "rk23", 1), ("python", 50.0, "rkc2", 1),  # rkc2 was 2: a second Simulation
    ("plugin", 5.0, "rk23", 1), ("plugin", 50.0, "rkc2", 1),  # were 2 and 3, then 1 and 2
])
def test_contexts_made_per_run(tmp_path, contexts, engine, bending, integrator, made):
    """``run.integrator = "auto"`` at Pe = inf: the stiffness is probed once on the run's
    Simulation, and rkc2 taken on the same Context. The Python engine takes the Python
    integrator in place; the plugin asks its own Context (``RPYIntegrator.
    estimateSpectralRadius``) and switches its integrator there (``RPYIntegrator.setMethod``:
    its kernel made again for rkc2)."""
    import knotmm.plugin
    from knotmm.config import load_run_file
    from knotmm.workflow import run

    if engine == "plugin" and not knotmm.plugin.available():
        pytest.skip(f"plugin not built: {knotmm.plugin.load_error()}")
    run(_cfg(bending, engine=engine), tmp_path / "r", progress=False)
    assert load_run_file(tmp_path / "r" / "run.toml")["run.integrator"] == integrator
    assert len(contexts) == made
    contexts.clear()
    run(_cfg(bending, engine=engine, integrator=integrator), tmp_path / "named", progress=False)
    assert len(contexts) == 1  # a named integrator: one Context


@pytest.mark.parametrize("engine", ["python", "plugin"])
def test_an_integrator_taken_in_place_steps_as_a_new_simulation(tmp_path, engine):
    """``auto`` taking rkc2 on the run's Simulation in place gives the run a named rkc2
    (same step and tolerance) gives, frame for frame."""
    import knotmm.plugin
    from knotmm.config import load_run_file
    from knotmm.io.dcd import read_dcd
    from knotmm.workflow import run

    if engine == "plugin" and not knotmm.plugin.available():
        pytest.skip(f"plugin not built: {knotmm.plugin.load_error()}")
    run(_cfg(50.0, engine=engine), tmp_path / "auto", progress=False)
    rec = load_run_file(tmp_path / "auto" / "run.toml")
    assert rec["run.integrator"] == "rkc2"
    run(_cfg(50.0, engine=engine, integrator="rkc2", timestep=rec["run.timestep"],
             tolerance=rec["run.tolerance"]), tmp_path / "named", progress=False)
    auto, named = (read_dcd(tmp_path / d / "trajectory.dcd")[0] for d in ("auto", "named"))
    assert auto.shape[0] > 1
    np.testing.assert_array_equal(auto, named)


@pytest.mark.parametrize("engine", ["python", "plugin"])
def test_a_resumed_run_starts_from_its_plan(tmp_path, monkeypatch, counts, engine):
    """``resume`` plans the run again from run.toml (:func:`knotmm.plan.resume_plan`): no
    integrator read from the run file by the registry, no ``Simulation.from_config``, one
    integrator and one Simulation; the resumed run's frames are those of a run never
    stopped."""
    import knotmm.plugin
    from knotmm.io.dcd import read_dcd
    from knotmm.workflow import resume, run

    if engine == "plugin" and not knotmm.plugin.available():
        pytest.skip(f"plugin not built: {knotmm.plugin.load_error()}")
    run(_cfg(50.0, engine=engine), tmp_path / "stopped", progress=False)
    run(_cfg(50.0, engine=engine, duration=1.0), tmp_path / "whole", progress=False)

    def refused(*args, **kwargs):
        raise AssertionError("a resumed run read its integrator or Simulation off run.toml")

    monkeypatch.setattr(registry, "integrator_from_config", refused)
    monkeypatch.setattr(simulation.Simulation, "from_config", classmethod(refused))
    counts.clear()
    result = resume(tmp_path / "stopped", progress=False, duration=1.0)
    assert (counts["integrators"], counts["simulations"]) == (1, 1)
    assert result.time == 1.0
    stopped, whole = (read_dcd(tmp_path / d / "trajectory.dcd")[0] for d in ("stopped", "whole"))
    assert stopped.shape[0] == whole.shape[0] == 3  # t = 0, 0.5, 1 tau_d
    np.testing.assert_array_equal(stopped, whole)
