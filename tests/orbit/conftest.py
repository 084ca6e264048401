"""A short deterministic run of T(2,3), N = 40, shared by the orbit tests (about 5 s)."""

from __future__ import annotations

import pytest


def make_run(directory, **changes):
    """Run T(2,3) for 60 tau_d (frames every 0.25 tau_d) with ``{"table.key": value}`` set."""
    from knotmm.config import RunConfig
    from knotmm.workflow import run

    data = {"knot": {"beads": 40}, "run": {"duration": 60.0},
            "output": {"frame_interval": 0.25, "directory": str(directory)}}
    for dotted, value in changes.items():
        table, key = dotted.split(".")
        data.setdefault(table, {})[key] = value
    run(RunConfig.from_dict(data), directory, progress=False)
    return directory


@pytest.fixture
def run_maker():
    """:func:`make_run`, for tests that need a run of their own."""
    return make_run


@pytest.fixture(scope="session")
def run40(tmp_path_factory):
    """Run directory of a right-handed T(2,3), N = 40, in its swirling state from ~15 tau_d."""
    return make_run(tmp_path_factory.mktemp("orbit") / "run40")


@pytest.fixture(scope="session")
def orbit40(run40):
    """(FlowMap, Orbit, OrbitStart) of run40, converged to 1e-9 d."""
    from knotmm.orbit.flow import make_flow
    from knotmm.orbit.shooting import solve_orbit
    from knotmm.orbit.start import refine_guess, start_from_run

    start = start_from_run(run40)
    flow = make_flow(start.positions, start.model)
    period, rotation, _ = refine_guess(flow, start.positions, start.tau_swirl)
    orbit = solve_orbit(flow, start.positions, period, rotation, tolerance=1e-9)
    assert orbit.converged, orbit.message
    return flow, orbit, start
