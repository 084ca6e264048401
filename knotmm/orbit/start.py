"""Where a shooting starts: a state of a saved run, a period and a rotation to go with it.

The run's own analysis (:func:`knotmm.analysis.core.analyze`) says whether the run has a
periodic window and gives ``tau_swirl``. The state is the frame nearest the middle of the
window (or a time the user names). The guess of the period is then sharpened by one
integration of :math:`1.3\\,\\tau_{swirl}`: the time in ``0.7 .. 1.3 tau_swirl`` at which the
chain, centred and turned back by the best rotation about ``z``, comes closest to its start.

A fixed point (a chain that converges to a steady shape: no gravity, a rigid ring) is
"periodic" with any period, and Newton happily shrinks the period to nothing: such a run is
refused with :data:`STEADY` (ConfigError, exit code 2), when its analysis says so and when the
chain's shape barely moves under the flow (:func:`shape_speed`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm.errors import ConfigError
from knotmm.orbit.flow import centre, rms, rotate_z
from knotmm.orbit.shooting import best_rotation

__all__ = ["OrbitStart", "STEADY", "FIXED_POINT_MOTION", "shape_speed", "start_from_run",
           "refine_guess"]

#: A start whose best recurrence is farther than this (d rms per bead) is not periodic.
MAX_RECURRENCE = 0.25
#: The refusal of a fixed point (the start of the one-line message).
STEADY = "the run converges to a steady shape: no periodic orbit"
#: A shape that moves less than this over a period guess (d rms per bead) is a fixed point;
#: a swirl moves its beads by about 2 pi C (C ~ 0.1-1 d) per period.
FIXED_POINT_MOTION = 1e-2


@dataclass
class OrbitStart:
    """A state of a run and the guesses that go with it.

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), in d
        Centred (float32 from the DCD, widened).
    time : float
        Its time in the run, tau_d.
    tau_swirl : float
        The run's swirl period from its analysis, tau_d.
    window : tuple of float
        The run's steady window, tau_d.
    config : knotmm.config.RunConfig
        The run's configuration (the continuation varies its keys).
    model : knotmm.model.parameters.ChainModel
        The run's model, from its plan's parts (:class:`knotmm.plan.PlanParts`).
    """

    positions: np.ndarray
    time: float
    tau_swirl: float
    window: tuple
    config: object
    model: object


def run_config(data):
    """The RunConfig of a loaded run (its ``run.toml``); ConfigError when it has none."""
    from knotmm.config import load_run_file

    if data.run_file is None:
        raise ConfigError(
            f"{data.directory}: no run.toml beside the trajectory, so the model is unknown; "
            f"orbits need a run directory written by knotmm run"
        )
    return load_run_file(data.run_file)


def start_from_run(run_dir, t: float | None = None) -> OrbitStart:
    """Read a run and pick the state to shoot from.

    Parameters
    ----------
    run_dir : str or Path
        A run directory of ``knotmm run``.
    t : float, optional
        Time of the starting frame, tau_d; default: the middle of the steady window.

    Raises
    ------
    ConfigError
        A run of several chains or of an open one, a Brownian run, a run without a periodic
        window, or ``t`` outside the run.
    """
    from knotmm.analysis.core import analyze
    from knotmm.analysis.shape import chains_of
    from knotmm.io.run_data import load_run
    from knotmm.plan import PlanParts

    data = load_run(Path(run_dir))
    chains = chains_of(data)
    if len(chains) != 1 or not chains[0][1]:
        what = (f"{len(chains)} chains" if len(chains) != 1 else "an open chain")
        raise ConfigError(
            f"{run_dir}: knotmm orbit handles one closed chain, and this run has {what}; "
            f"use a run of one knot"
        )
    cfg = run_config(data)
    parts = PlanParts.of(cfg)  # the run's plan, as far as a saved run needs it
    if math.isfinite(parts.stepping.peclet):
        raise ConfigError(
            f"{run_dir}: run.peclet = {parts.stepping.peclet:g}; periodic orbits are states of the "
            f"deterministic model: use a run with run.peclet unset (infinite)"
        )
    result = analyze(data, knot_samples=0, fit=False)
    detection = result.extra.get("swirl_detection") or {}
    if not result.swirl_detected and detection.get("steady_shape"):
        raise ConfigError(f"{run_dir}: {STEADY}; the analysis says {detection.get('reason')}")
    if not result.swirl_detected or not (result.tau_swirl and result.tau_swirl > 0):
        why = "; ".join(result.notes[:2]) if getattr(result, "notes", None) else ""
        raise ConfigError(
            f"{run_dir} has no periodic window (the analysis detects no swirl"
            f"{': ' + why if why else ''}); run it longer or give --t at a time when it swirls"
        )
    times = np.asarray(data.times, dtype=float)
    window = (float(result.window.t0), float(result.window.t1))
    if t is None:
        t = 0.5 * (window[0] + window[1])
    elif not times[0] <= t <= times[-1]:
        raise ConfigError(
            f"--t {t:g}: outside the run ({times[0]:g} .. {times[-1]:g} tau_d); its periodic "
            f"window is {window[0]:g} .. {window[1]:g}"
        )
    k = int(np.argmin(np.abs(times - t)))
    x = centre(np.asarray(data.positions[k], dtype=float))
    return OrbitStart(x, float(times[k]), float(result.tau_swirl), window, cfg, parts.model)


def shape_speed(flow, x: np.ndarray) -> float:
    """How fast the shape of ``x`` changes: the rms bead velocity left when the rigid motions
    (a translation, a rotation about ``z``) are taken out, in d/tau_d.

    A relative equilibrium (a steady shape falling and turning) gives 0; a swirl about
    ``2 pi C / tau_swirl``.

    Parameters
    ----------
    flow : knotmm.orbit.flow.FlowMap
    x : ndarray, shape (n_beads, 3), in d
    """
    x = centre(np.asarray(x, dtype=float))
    v = flow.velocity(x)
    v = v - v.mean(axis=0)
    turn = np.zeros_like(x)
    turn[:, 0], turn[:, 1] = -x[:, 1], x[:, 0]  # e_z x r
    norm = float((turn * turn).sum())
    if norm > 0:
        v = v - turn * float((v * turn).sum()) / norm
    return rms(v)


def refine_guess(flow, x: np.ndarray, tau: float, samples: int = 130):
    """Sharpen the period and find the rotation per period from one integration.

    Parameters
    ----------
    flow : knotmm.orbit.flow.FlowMap
    x : ndarray, shape (n_beads, 3), in d
        The starting state (centred).
    tau : float
        The period guess (e.g. the run's ``tau_swirl``), tau_d.
    samples : int
        States sampled over ``1.3 tau``.

    Returns
    -------
    period, rotation, distance : float
        The best return time (tau_d), the rotation then (rad) and the distance left (d rms
        per bead).
    """
    frames = flow.trajectory(x, 1.3 * tau, samples)
    times = np.linspace(0.0, 1.3 * tau, samples + 1)
    best = (math.inf, tau, 0.0)
    for time, frame in zip(times, frames, strict=False):
        if time < 0.7 * tau:
            continue
        a = centre(frame)
        angle = best_rotation(a, x)
        dist = rms(rotate_z(a, -angle) - x)
        if dist < best[0]:
            best = (dist, float(time), angle)
    return best[1], best[2], best[0]
