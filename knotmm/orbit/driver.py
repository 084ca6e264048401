"""``knotmm orbit`` as a function: from a saved run to its periodic orbit and its stability.

:func:`orbit_of_run` reads the run (:mod:`knotmm.orbit.start`), converges the orbit
(:mod:`knotmm.orbit.shooting`), computes the leading Floquet multipliers
(:mod:`knotmm.orbit.floquet`), names the leading mode (:mod:`knotmm.orbit.modes`) and writes
the files of :mod:`knotmm.orbit.output`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

from knotmm.errors import ConfigError
from knotmm.orbit.floquet import floquet
from knotmm.orbit.flow import make_flow
from knotmm.orbit.modes import describe_mode
from knotmm.orbit.output import orbit_summary, write_orbit_files
from knotmm.orbit.shooting import DEFAULT_TOLERANCE, solve_orbit
from knotmm.orbit.start import MAX_RECURRENCE, refine_guess, start_from_run

__all__ = ["OrbitReport", "orbit_of_run", "DEFAULT_MODES"]

log = logging.getLogger(__name__)

#: Leading Floquet multipliers computed by default.
DEFAULT_MODES = 10
#: Where results go inside the run directory by default.
DEFAULT_SUBDIR = "orbit"


@dataclass
class OrbitReport:
    """What :func:`orbit_of_run` found.

    Attributes
    ----------
    orbit : knotmm.orbit.shooting.Orbit
    floquet : knotmm.orbit.floquet.FloquetResult or None
        None when the orbit did not converge or ``modes = 0``.
    summary : dict
        The content of ``orbit.json``.
    out : Path
        Where the files went.
    """

    orbit: object
    floquet: object
    summary: dict
    out: Path


def _check_modes(modes) -> None:
    if not isinstance(modes, int) or modes < 0:
        raise ConfigError(f"--modes {modes!r}: expected an integer >= 0 (default 10)")


def _first_orbit(run_dir, t, timestep, tolerance, engine, threads):
    """Read the run, build the flow map, sharpen the guess and shoot.

    Returns (OrbitStart, FlowMap, Orbit, initial recurrence distance in d).
    """
    from knotmm.model.parameters import ChainModel

    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 1):
        raise ConfigError(f"--tolerance {tolerance!r}: expected a residual in d, e.g. 1e-8")
    start = start_from_run(run_dir, t)
    flow = make_flow(start.positions, ChainModel.from_config(start.config), timestep,
                     engine=engine, threads=threads)
    period, rotation, distance = refine_guess(flow, start.positions, start.tau_swirl)
    if distance > MAX_RECURRENCE:
        raise ConfigError(
            f"{run_dir}: the state at t = {start.time:g} tau_d does not come back within "
            f"{MAX_RECURRENCE:g} d rms per bead in 0.7-1.3 tau_swirl (closest: {distance:.3g} d "
            f"at {period:.4g} tau_d); give --t inside the periodic window "
            f"{start.window[0]:g} .. {start.window[1]:g}"
        )
    orbit = solve_orbit(flow, start.positions, period, rotation, tolerance=tolerance)
    return start, flow, orbit, distance


def orbit_of_run(run_dir, t: float | None = None, modes: int = DEFAULT_MODES, out=None,
                 timestep: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
                 engine: str = "auto", threads: int = 1) -> OrbitReport:
    """Find the periodic orbit of a run's swirling state and its Floquet multipliers.

    Parameters
    ----------
    run_dir : str or Path
        A deterministic run directory of ``knotmm run`` with a periodic window.
    t : float, optional
        Time (tau_d) of the state to start from; default the middle of the steady window.
    modes : int
        Leading non-neutral multipliers to compute (0: none).
    out : str or Path, optional
        Output directory; default ``RUN_DIR/orbit``.
    timestep : float, optional
        Fixed step of the flow map (Heun), tau_d; default: 0.01, or less where the chain is
        stiffer (:func:`knotmm.orbit.flow.make_flow`).
    tolerance : float
        Newton's target residual, d rms per bead.
    engine : {"auto", "plugin", "python"}
    threads : int
        Threads of the RPY pair loop.

    Returns
    -------
    OrbitReport

    Raises
    ------
    ConfigError
        Bad arguments, a Brownian run, a run without a periodic window.
    """
    _check_modes(modes)
    wall = time.perf_counter()
    start, flow, orbit, distance = _first_orbit(run_dir, t, timestep, tolerance, engine,
                                                threads)
    result = shape = None
    if orbit.converged and modes > 0:
        result = floquet(flow, orbit, k=min(modes, orbit.positions.size - 8))
        if len(result.multipliers):
            shape = describe_mode(orbit.positions, result.modes[0])
    extra = {
        "run": str(Path(run_dir).name),
        "start_time": start.time,
        "run_tau_swirl": start.tau_swirl,
        "run_window": list(start.window),
        "initial_recurrence": distance,
        "timestep": flow.timestep,
        "engine": flow.engine,
        "flow_integrations": flow.n_flows,
        "wall_time_s": None,
    }
    summary = orbit_summary(orbit, result, shape, extra)
    out = Path(out) if out is not None else Path(run_dir) / DEFAULT_SUBDIR
    summary["wall_time_s"] = round(time.perf_counter() - wall, 2)
    write_orbit_files(out, flow, orbit, result, summary)
    return OrbitReport(orbit, result, summary, out)


def continuation_of_run(run_dir, spec: str, points: int = 8, modes: int = DEFAULT_MODES,
                        out=None, t: float | None = None, timestep: float | None = None,
                        tolerance: float = DEFAULT_TOLERANCE, engine: str = "auto",
                        threads: int = 1, on_point=None):
    """Follow the orbit of a run along a parameter and write the branch.

    Parameters
    ----------
    run_dir : str or Path
    spec : str
        ``KEY=START:STOP`` (:func:`knotmm.orbit.continuation.parse_range`).
    points : int
        Points asked for between START and STOP.
    modes, out, t, timestep, tolerance, engine, threads
        As in :func:`orbit_of_run` (``out`` default ``RUN_DIR/orbit``).
    on_point : callable, optional
        Called with each :class:`~knotmm.orbit.continuation.ContinuationPoint`.

    Returns
    -------
    (list of ContinuationPoint, list of Bifurcation, Path)
    """
    from knotmm.orbit.continuation import (
        DISCRETE_KEYS,
        continue_orbit,
        find_bifurcations,
        parse_range,
    )
    from knotmm.orbit.output import write_branch

    key, a, b = parse_range(spec)
    _check_modes(modes)
    wall = time.perf_counter()
    start, _, orbit, _ = _first_orbit(run_dir, t, timestep, tolerance, engine, threads)
    if not orbit.converged:
        raise ConfigError(
            f"{run_dir}: the orbit of the run did not converge (residual {orbit.residual:.3g} d,"
            f" {orbit.message}); nothing to continue from"
        )

    def flow_for(model, positions, step=timestep):
        return make_flow(positions, model, step, engine=engine, threads=threads)

    branch = continue_orbit(orbit, start.config, key, a, b, flow_for, points=points,
                            modes=modes, tolerance=tolerance, on_point=on_point)
    bifurcations = find_bifurcations(branch, discrete=key in DISCRETE_KEYS)
    out = Path(out) if out is not None else Path(run_dir) / DEFAULT_SUBDIR
    extra = {"run": str(Path(run_dir).name), "requested": [a, b], "points_asked": points,
             "reached_stop": bool(branch) and (branch[-1].value - a) / (b - a) >= 0.99,
             "timesteps": [p.orbit.timestep for p in branch],
             "wall_time_s": round(time.perf_counter() - wall, 2)}
    write_branch(out, key, branch, bifurcations, modes, extra)
    return branch, bifurcations, out
