"""``knotmm orbit`` as a function: from a saved run to its periodic orbit and its stability.

:func:`orbit_of_run` reads the run (:mod:`knotmm.orbit.start`), converges the orbit
(:mod:`knotmm.orbit.shooting`), computes the leading Floquet multipliers
(:mod:`knotmm.orbit.floquet`), names the leading mode (:mod:`knotmm.orbit.modes`) and writes
the files of :mod:`knotmm.orbit.output`; :func:`continuation_of_run` follows it along a
parameter. Both check every argument and the output directory before the computation
(one line, exit code 2), and hold the output directory locked while they write there
(:class:`knotmm.io.rundir.RunLock`: a second ``knotmm orbit`` on it is refused).
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

from knotmm.errors import ConfigError, RunDirectoryError
from knotmm.io.rundir import RUN_FILE, RunLock, check_output_directory, writing
from knotmm.orbit.floquet import floquet
from knotmm.orbit.flow import make_flow
from knotmm.orbit.modes import describe_mode
from knotmm.orbit.output import orbit_summary, write_orbit_files
from knotmm.orbit.shooting import DEFAULT_TOLERANCE, solve_orbit
from knotmm.orbit.start import (
    FIXED_POINT_MOTION,
    MAX_RECURRENCE,
    STEADY,
    refine_guess,
    shape_speed,
    start_from_run,
)

__all__ = ["OrbitReport", "OrbitInterrupted", "orbit_of_run", "continuation_of_run",
           "DEFAULT_MODES"]

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


class OrbitInterrupted(KeyboardInterrupt):
    """An orbit or a continuation stopped by a signal; ``message`` says what was kept."""

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


def _check_modes(modes) -> None:
    if isinstance(modes, bool) or not isinstance(modes, int) or modes < 0:
        raise ConfigError(f"--modes {modes!r}: expected an integer >= 0 (default 10)")


def _check_modes_fit(modes: int, n_beads: int) -> None:
    """A chain of N beads has 3N - 5 non-neutral multipliers; ARPACK finds at most 3N - 8."""
    limit = 3 * n_beads - 8
    if modes > limit:
        raise ConfigError(
            f"--modes {modes}: a chain of {n_beads} beads has at most {limit} multipliers "
            f"to compute (3N - 8); ask for at most {limit}"
        )


def _check_numbers(timestep, tolerance) -> None:
    if timestep is not None and not (isinstance(timestep, (int, float))
                                     and math.isfinite(timestep) and 0 < timestep <= 0.05):
        raise ConfigError(
            f"--timestep {timestep!r}: the orbit's fixed step must be in (0, 0.05] tau_d "
            f"(Heun is unstable above ~0.04 for the default bond stiffness); leave it out for "
            f"an automatic stable step, or try 0.01"
        )
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 1):
        raise ConfigError(f"--tolerance {tolerance!r}: expected a residual in d, e.g. 1e-8")


def _output_directory(run_dir, out) -> tuple[Path, bool]:
    """``out`` (default ``RUN_DIR/orbit``), checked to take files before the computation,
    and whether it was created by this check."""
    out = Path(out) if out is not None else Path(run_dir) / DEFAULT_SUBDIR
    created = not out.exists()
    if (out / RUN_FILE).exists():
        raise RunDirectoryError(
            f"--out {str(out)!r} holds a knotmm run ({RUN_FILE}); the orbit's files "
            f"(topology.pdb, ...) would mix with the run's: choose another directory, e.g. "
            f"{str(out / DEFAULT_SUBDIR)!r}"
        )
    check_output_directory(out)
    return out, created


@contextlib.contextmanager
def _owned(out: Path, created: bool):
    """Hold ``out`` locked; remove it again if it was created here and is left empty."""
    try:
        with RunLock(out, what="orbit"):
            yield
    finally:
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only when empty: nothing was written


def _make_flow_map(start, timestep, engine, threads):
    return make_flow(start.positions, start.model, timestep, engine=engine, threads=threads)


def _shoot(run_dir, start, flow, tolerance):
    """Sharpen the guess and shoot; returns (Orbit, initial recurrence distance in d).

    A fixed point is refused (:data:`knotmm.orbit.start.STEADY`): before shooting, when its
    shape moves less than ``FIXED_POINT_MOTION`` over the period guess; after, when Newton
    shrank the period below half the guess (any period fits a fixed point).
    """
    motion = shape_speed(flow, start.positions) * start.tau_swirl
    if motion < FIXED_POINT_MOTION:
        raise ConfigError(
            f"{run_dir}: {STEADY} (at t = {start.time:g} tau_d the shape moves "
            f"{motion:.2g} d rms per bead over the period guess {start.tau_swirl:.4g} tau_d, "
            f"below {FIXED_POINT_MOTION:g} d: a fixed point)"
        )
    period, rotation, distance = refine_guess(flow, start.positions, start.tau_swirl)
    if distance > MAX_RECURRENCE:
        raise ConfigError(
            f"{run_dir}: the state at t = {start.time:g} tau_d does not come back within "
            f"{MAX_RECURRENCE:g} d rms per bead in 0.7-1.3 tau_swirl (closest: {distance:.3g} d "
            f"at {period:.4g} tau_d); give --t inside the periodic window "
            f"{start.window[0]:g} .. {start.window[1]:g}"
        )
    orbit = solve_orbit(flow, start.positions, period, rotation, tolerance=tolerance)
    if orbit.period < 0.5 * period:
        raise ConfigError(
            f"{run_dir}: {STEADY} (Newton shrank the period from {period:.4g} to "
            f"{orbit.period:.3g} tau_d: a fixed point, which any period fits)"
        )
    return orbit, distance


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
        Leading non-neutral multipliers to compute (0: none; at most ``3 N - 8``).
    out : str or Path, optional
        Output directory; default ``RUN_DIR/orbit``. Locked while the orbit is computed
        and written; the files of an earlier orbit there are replaced.
    timestep : float, optional
        Fixed step of the flow map (Heun), tau_d, in (0, 0.05]; default: 0.01, or less
        where the chain is stiffer (:func:`knotmm.orbit.flow.make_flow`).
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
    knotmm.io.rundir.OutputError
        ``out`` cannot take files (exit code 2, before the computation);
        :class:`~knotmm.io.rundir.WriteFault` when writing fails (exit code 3).
    knotmm.errors.RunDirectoryError
        ``out`` is a file, a run directory, or locked by another process.
    OrbitInterrupted
        Stopped by a signal (Ctrl-C, SIGTERM); its message says what was kept.
    """
    _check_modes(modes)
    _check_numbers(timestep, tolerance)
    wall = time.perf_counter()
    start = start_from_run(run_dir, t)
    _check_modes_fit(modes, start.positions.shape[0])
    out, created = _output_directory(run_dir, out)
    writing_files = False
    try:
        with _owned(out, created):
            flow = _make_flow_map(start, timestep, engine, threads)
            orbit, distance = _shoot(run_dir, start, flow, tolerance)
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
            summary["wall_time_s"] = round(time.perf_counter() - wall, 2)
            writing_files = True
            write_orbit_files(out, flow, orbit, result, summary)
    except KeyboardInterrupt as exc:
        raise OrbitInterrupted(
            f"interrupted{_by(exc)} while "
            + (f"writing the orbit's files in {str(out)!r}: the files written so far are "
               f"kept (each one whole); run knotmm orbit again to write them all"
               if writing_files else
               f"computing the orbit: nothing was written ({str(out)!r} is as it was); "
               f"run knotmm orbit again")
        ) from None
    return OrbitReport(orbit, result, summary, out)


def _by(exc) -> str:
    """`` by SIGINT (Ctrl-C)`` from a stop request or a plain KeyboardInterrupt."""
    from knotmm.engine.interrupt import describe_signal, stop_signal

    name = getattr(exc, "signal", None) or stop_signal()
    return f" by {describe_signal(name)}" if name else ""


def continuation_of_run(run_dir, spec: str, points: int = 8, modes: int = DEFAULT_MODES,
                        out=None, t: float | None = None, timestep: float | None = None,
                        tolerance: float = DEFAULT_TOLERANCE, engine: str = "auto",
                        threads: int = 1, on_point=None, resume: bool = False):
    """Follow the orbit of a run along a parameter and write the branch.

    Each converged point is written as it comes (``continuation.csv``, ``.json``, ``.png``
    and ``continuation_state.npz`` rewritten atomically), so a stopped continuation keeps
    every point it found, and ``resume=True`` goes on from them.

    Parameters
    ----------
    run_dir : str or Path
    spec : str
        ``KEY=START:STOP`` (:func:`knotmm.orbit.continuation.parse_range`).
    points : int
        Points asked for between START and STOP (>= 2).
    modes, out, t, timestep, tolerance, engine, threads
        As in :func:`orbit_of_run` (``out`` default ``RUN_DIR/orbit``).
    on_point : callable, optional
        Called with each new :class:`~knotmm.orbit.continuation.ContinuationPoint` (not with
        those read back by ``resume``).
    resume : bool
        Go on with the continuation saved in ``out`` (same ``spec``, ``points``, ``modes``,
        ``tolerance`` and ``timestep``; ConfigError if they differ). A finished one is
        written again and returned as it is.

    Returns
    -------
    (list of ContinuationPoint, list of Bifurcation, Path)

    Raises
    ------
    As :func:`orbit_of_run`; :class:`OrbitInterrupted` says how many points were kept.
    """
    from knotmm.orbit.continuation import (
        DISCRETE_KEYS,
        check_range,
        continue_orbit,
        find_bifurcations,
        parse_range,
    )
    from knotmm.orbit.output import BRANCH_OUTPUTS, read_branch, remove_outputs, write_branch

    key, a, b = parse_range(spec)
    _check_modes(modes)
    _check_numbers(timestep, tolerance)
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise ConfigError(f"--points {points!r}: need an integer >= 2")
    wall = time.perf_counter()
    start = start_from_run(run_dir, t)
    check_range(start.config, key, a, b, points)
    n_beads = start.positions.shape[0]
    if key in DISCRETE_KEYS:
        n_beads = min(n_beads, int(a), int(b))
    _check_modes_fit(modes, n_beads)
    out, created = _output_directory(run_dir, out)
    options = {"parameter": key, "start": a, "stop": b, "points": points, "modes": modes,
               "tolerance": tolerance, "timestep": timestep}
    branch: list = []
    try:
        with _owned(out, created):
            finished = False
            if resume:
                saved, branch = read_branch(out)
                _same_options(out, saved, options)
                finished = bool(saved.get("finished"))
            else:
                with writing(out):
                    remove_outputs(out, BRANCH_OUTPUTS)

            def extra(done: bool) -> dict:
                return {"run": str(Path(run_dir).name), "requested": [a, b],
                        "points_asked": points,
                        "reached_stop": bool(branch) and (branch[-1].value - a) / (b - a)
                        >= 0.99,
                        "complete": done,
                        "timesteps": [p.orbit.timestep for p in branch],
                        "wall_time_s": round(time.perf_counter() - wall, 2)}

            def save(done: bool) -> None:
                # the branch's files are rewritten together: SIGINT and SIGTERM wait for the
                # few milliseconds it takes, so even a second Ctrl-C (which stops at once)
                # never leaves csv, json and state telling different stories
                from knotmm.workflow import _signals_held

                with _signals_held():
                    write_branch(out, key, branch,
                                 find_bifurcations(branch, key in DISCRETE_KEYS), modes,
                                 extra(done), state=options | {"finished": done})

            def add(point) -> None:
                branch.append(point)
                save(False)
                if on_point is not None:
                    on_point(point)

            if not finished:
                orbit = None
                if not branch:
                    flow = _make_flow_map(start, timestep, engine, threads)
                    orbit, _ = _shoot(run_dir, start, flow, tolerance)
                    if not orbit.converged:
                        raise ConfigError(
                            f"{run_dir}: the orbit of the run did not converge (residual "
                            f"{orbit.residual:.3g} d, {orbit.message}); nothing to continue "
                            f"from"
                        )

                def flow_for(model, positions, step=timestep):
                    return make_flow(positions, model, step, engine=engine, threads=threads)

                continue_orbit(orbit, start.model, key, a, b, flow_for, points=points,
                               modes=modes, tolerance=tolerance, on_point=add,
                               branch=list(branch))
            save(True)
    except KeyboardInterrupt as exc:
        names = "continuation.csv and continuation.json"
        n = len(branch)
        kept = (f"{'the 1 converged point is' if n == 1 else f'the {n} converged points are'} "
                f"kept in {names} in {str(out)!r}; run the same knotmm orbit command with "
                f"--resume to go on" if branch else
                "no point had converged, nothing was kept; run knotmm orbit again")
        raise OrbitInterrupted(f"interrupted{_by(exc)} during the continuation: {kept}") \
            from None
    bifurcations = find_bifurcations(branch, discrete=key in DISCRETE_KEYS)
    return branch, bifurcations, out


def _same_options(out, saved: dict, options: dict) -> None:
    """ConfigError naming the first option ``--resume`` was given differently."""
    flags = {"parameter": "--continue", "start": "--continue", "stop": "--continue",
             "points": "--points", "modes": "--modes", "tolerance": "--tolerance",
             "timestep": "--timestep"}
    for name, value in options.items():
        if saved.get(name) != value:
            raise ConfigError(
                f"--resume: the continuation in {str(out)!r} was started with {name} = "
                f"{saved.get(name)!r}, not {value!r}; resume it with the options it was "
                f"started with ({flags[name]}), or start a new one without --resume"
            )

