"""Newton-Krylov shooting for a relative periodic orbit of the sedimenting chain.

Unknowns: the bead positions ``x`` (shape ``(n_beads, 3)``, d), the period ``T`` (tau_d) and
the rotation per period ``theta`` (rad, about ``z``). The orbit condition is

    r(x, T, theta) = R_z(-theta) (phi_T(x) - c(phi_T(x))) - x = 0

with ``c`` the centroid: after one period the shape repeats up to a translation (free, removed
by centring) and a rotation by ``theta``. Because ``phi_T(x) - c`` does not depend on where
``x`` sits, the mean of ``r`` is ``-c(x)``, so ``r = 0`` also puts ``x``'s centroid at the
origin: the translations are fixed without an extra equation. The remaining continuous
symmetries, a shift along the orbit and a rotation about ``z``, are fixed by asking each
Newton correction ``dx`` to be orthogonal to the shape velocity ``P f(x)`` and to the
rotation field ``e_z x x`` (``P`` removes the mean). Each Newton step solves the bordered
system

    [ R(-theta) P Dphi - I   R(-theta) P f(phi_T x)   -J R(-theta) P phi_T x ] [dx     ]   [ -r ]
    [ (P f(x))^T             0                         0                     ] [dT     ] = [  0 ]
    [ (e_z x x)^T            0                         0                     ] [dtheta ]   [  0 ]

by GMRES, with ``Dphi v`` from finite differences of the flow map
(:meth:`knotmm.orbit.flow.FlowMap.jvp`), and takes the step with a backtracking line search.
The residual reported is the rms over beads of ``r``, in d.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.linalg import LinearOperator, gmres

from knotmm.errors import SimulationFault
from knotmm.orbit.flow import centre, rms, rotate_z, rotation_generator

__all__ = ["Orbit", "best_rotation", "bordered_operator", "residual", "solve_orbit"]

log = logging.getLogger(__name__)

#: Residual (d rms per bead) at which Newton stops.
DEFAULT_TOLERANCE = 1e-8
#: A Newton correction moves no bead by more than this (d); larger ones are scaled down.
MAX_MOVE = 0.5


@dataclass
class Orbit:
    """A relative periodic orbit (or the last Newton iterate, when not converged).

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), in d
        A state on the orbit, centroid at the origin.
    period : float
        ``T``, in tau_d.
    rotation : float
        Rotation about ``z`` per period, rad (positive: counterclockwise from above).
    displacement : ndarray, shape (3,), in d
        Centroid displacement over one period (``z``: the fall).
    residual : float
        ``rms(r)``, in d per bead.
    converged : bool
        ``residual <= tolerance``.
    iterations : int
        Newton iterations taken.
    history : list of float
        Residual after each iteration (the first entry: the initial guess).
    message : str
        Why Newton stopped.
    n_flows : int
        Integrations over a period spent.
    timestep : float
        The fixed step of the flow map the orbit belongs to, tau_d.
    """

    positions: np.ndarray
    period: float
    rotation: float
    displacement: np.ndarray
    residual: float
    converged: bool
    iterations: int
    history: list = field(default_factory=list)
    message: str = ""
    n_flows: int = 0
    timestep: float = math.nan

    @property
    def sedimentation_velocity(self) -> float:
        """Falling speed of the centroid, ``-dz / T``, in d/tau_d (positive: downward)."""
        return float(-self.displacement[2] / self.period)

    @property
    def n_beads(self) -> int:
        return int(self.positions.shape[0])


def best_rotation(a: np.ndarray, b: np.ndarray) -> float:
    """The angle ``theta`` minimising ``|R_z(-theta) a - b|^2`` (both centred), in rad."""
    cross = np.sum(b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0])
    dot = np.sum(b[:, 0] * a[:, 0] + b[:, 1] * a[:, 1])
    return float(math.atan2(cross, dot))


def residual(flow, x: np.ndarray, period: float, rotation: float):
    """The orbit residual ``r`` and ``phi_T(x)``.

    Returns
    -------
    r : ndarray, shape (n_beads, 3), in d
    end : ndarray, shape (n_beads, 3), in d
        ``phi_T(x)`` (true positions).
    """
    end = flow(x, period)
    return rotate_z(centre(end), -rotation) - x, end


def bordered_operator(flow, x, period, rotation, end, column=None, row=None):
    """The Newton matrix of the orbit condition as a LinearOperator.

    On ``(dx (3N), dT, dtheta)``; with ``column`` (``dr/dp``, shape (3N,)) and ``row`` (shape
    (3N + 3,)) one more unknown ``dp`` and one more equation ``row . du`` (the arclength
    condition of :mod:`knotmm.orbit.continuation`).
    """
    n3 = x.size
    col_t = rotate_z(centre(flow.velocity(end)), -rotation).ravel()
    col_theta = -rotation_generator(rotate_z(centre(end), -rotation)).ravel()
    phase = centre(flow.velocity(x)).ravel()
    phase /= np.linalg.norm(phase)
    spin = rotation_generator(centre(x)).ravel()
    spin /= np.linalg.norm(spin)
    size = n3 + 2 + (column is not None)

    def matvec(u):
        u = np.asarray(u, dtype=float).ravel()
        dx = u[:n3]
        jv = flow.jvp(x, period, end, dx)
        top = rotate_z(centre(jv), -rotation).ravel() - dx + col_t * u[n3] + col_theta * u[n3 + 1]
        tail = [phase @ dx, spin @ dx]
        if column is not None:
            top = top + column * u[n3 + 2]
            tail.append(row @ u)
        return np.concatenate([top, tail])

    return LinearOperator((size, size), matvec=matvec, dtype=float)


def solve_orbit(flow, x0: np.ndarray, period: float, rotation: float, *,
                tolerance: float = DEFAULT_TOLERANCE, max_iterations: int = 25,
                gmres_tolerance: float = 1e-4, max_krylov: int = 200) -> Orbit:
    """Converge a relative periodic orbit by Newton-Krylov shooting.

    Parameters
    ----------
    flow : knotmm.orbit.flow.FlowMap
    x0 : array_like, shape (n_beads, 3), in d
        Initial guess (any position; it is centred).
    period : float
        Initial guess of ``T``, tau_d.
    rotation : float
        Initial guess of the rotation per period, rad.
    tolerance : float
        Target residual, d rms per bead.
    max_iterations : int
        Newton iterations at most.
    gmres_tolerance : float
        Relative tolerance of each linear solve (an inexact Newton method).
    max_krylov : int
        GMRES iterations at most per Newton step (one flow integration each).

    Returns
    -------
    Orbit
        ``converged`` says whether ``residual <= tolerance``; otherwise ``message`` says why
        Newton stopped and the best iterate is returned.
    """
    x = centre(np.asarray(x0, dtype=float))
    period, rotation = float(period), float(rotation)
    start_flows = flow.n_flows
    r, end = residual(flow, x, period, rotation)
    res = rms(r)
    history = [res]
    message = "reached the iteration limit"
    for iteration in range(1, max_iterations + 1):
        if res <= tolerance:
            break
        op = bordered_operator(flow, x, period, rotation, end)
        rhs = np.concatenate([-r.ravel(), [0.0, 0.0]])
        du, info = gmres(op, rhs, rtol=gmres_tolerance, atol=0.0, restart=max_krylov,
                         maxiter=1)
        dx = du[: x.size].reshape(x.shape)
        largest = float(np.max(np.linalg.norm(dx, axis=1)))
        scale = min(1.0, MAX_MOVE / largest) if largest > 0 else 1.0
        accepted = False
        for _ in range(8):
            trial = (x + scale * dx, period + scale * du[-2], rotation + scale * du[-1])
            if trial[1] > 0:  # else: halve, as for a chain that breaks on the way
                try:
                    r_new, end_new = residual(flow, *trial)
                    accepted = rms(r_new) < res
                except SimulationFault:
                    pass
            if accepted:
                break
            scale /= 2
        if not accepted:
            message = "the line search found no decrease (Newton stalled)"
            break
        x, period, rotation = trial
        r, end, res = r_new, end_new, rms(r_new)
        history.append(res)
        log.info("newton %d: residual %.3e d, T = %.8f, theta = %.8f, step %.3g, gmres %s",
                 iteration, res, period, rotation, scale, info)
    converged = res <= tolerance
    if converged:
        message = "converged"
    return Orbit(
        positions=x,
        period=period,
        rotation=rotation,
        displacement=end.mean(axis=0) - x.mean(axis=0),
        residual=res,
        converged=converged,
        iterations=len(history) - 1,  # Newton steps taken
        history=history,
        message=message,
        n_flows=flow.n_flows - start_flows,
        timestep=flow.timestep,
    )
