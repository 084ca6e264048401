"""``run.integrator = "auto"`` at Pe = inf picks by the chain's measured stiffness."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.dynamics.registry import AUTO_STIFFNESS, auto_deterministic


def test_policy_threshold():
    assert auto_deterministic(0.5 * AUTO_STIFFNESS) == "rk23"
    assert auto_deterministic(2.0 * AUTO_STIFFNESS) == "rkc2"


@pytest.mark.parametrize("engine", ["python", "plugin"])
def test_stiffness_is_the_largest_eigenvalue_of_a_dense_jacobian(engine):
    """Simulation.stiffness against the eigenvalues of the velocity Jacobian built column by
    column in the test (8 beads, Reference platform), times RKC's 1.2 margin. The power
    iteration stops when its estimate changes by under 1 % (at most 30 rounds), so it may
    fall short of the top eigenvalue by some per cent, never exceed it. The plugin engine
    asks the plugin's rkc2 for its estimate."""
    from reference_model import dense_jacobian, flat_ring

    import knotmm.plugin
    from knotmm.dynamics.deterministic import RK23
    from knotmm.engine.simulation import Simulation
    from knotmm.model.parameters import ChainModel

    if engine == "plugin" and not knotmm.plugin.available():
        pytest.skip(f"plugin not built: {knotmm.plugin.load_error()}")
    x = flat_ring(8, wave=0.05)
    sim = Simulation(x, ChainModel(bending_stiffness=50.0), RK23(0.01), platform="Reference",
                     engine=engine)
    jac = dense_jacobian(sim.velocity, x)
    largest = np.max(np.abs(np.linalg.eigvals(jac)))
    before = sim.n_evaluations
    assert 0.85 * 1.2 * largest <= sim.stiffness() <= 1.01 * 1.2 * largest
    assert sim.n_evaluations == before  # the measurement is not counted


@pytest.mark.parametrize(("bending", "expected"), [(5.0, "rk23"), (50.0, "rkc2")])
def test_run_records_the_integrator_auto_picked(tmp_path, bending, expected):
    from knotmm.config import RunConfig, load_run_file
    from knotmm.workflow import run

    cfg = RunConfig.from_dict({"knot": {"beads": 40},
                               "model": {"bending_stiffness": bending},
                               "run": {"duration": 0.5, "topology_check_interval": 0.0}})
    run(cfg, tmp_path / "r", progress=False)
    assert load_run_file(tmp_path / "r" / "run.toml")["run.integrator"] == expected


def test_plugin_stiffness_of_a_start_it_cannot_step_is_an_estimate_not_a_traceback():
    """Issue 30: the plugin's rkc2 probe step fails (step-size underflow) at gravity 1e100;
    the estimate, made at the step's start, is still returned, and the run then reports its
    own fault. At such forces the velocity Jacobian is that of M(x) g, linear in g: the
    estimate scales as the gravity does (checked against gravity 1e6, which steps)."""
    from reference_model import flat_ring

    import knotmm.plugin
    from knotmm.dynamics.deterministic import RK23
    from knotmm.engine.simulation import Simulation
    from knotmm.model.parameters import ChainModel

    if not knotmm.plugin.available():
        pytest.skip(f"plugin not built: {knotmm.plugin.load_error()}")
    x = flat_ring(8, wave=0.05)

    def stiffness(gravity):
        return Simulation(x, ChainModel(gravity=gravity), RK23(0.01), platform="Reference",
                          engine="plugin").stiffness()

    ratio = stiffness(1e100) / stiffness(1e6)
    assert ratio == pytest.approx(1e94, rel=0.05)
