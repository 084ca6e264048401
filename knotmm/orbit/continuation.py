"""Following an orbit along a parameter, and where its stability changes.

A model parameter ``p`` (a float key of ``[model]``, e.g. ``model.bending_stiffness``) is
followed by **pseudo-arclength continuation**: the unknowns are ``U = (x, T, theta, p)``;
from the last two points the secant ``tau = (U_1 - U_0) / |U_1 - U_0|`` predicts
``U_pred = U_1 + ds tau``, and Newton solves the orbit condition of
:mod:`knotmm.orbit.shooting` together with ``<U - U_pred, tau> = 0``, so the branch can be
followed through a fold where ``p`` turns back. ``dr/dp`` comes from a flow map built at
``p + dp`` (one more integration per Newton step). The first step is a plain step in ``p``.

``knot.beads`` is not continuous: each point is a new orbit, started from the previous one
resampled to the new number of beads (the ring stretched by ``N'/N`` so bonds keep their
length), its period scaled by ``N'/N`` and sharpened as for a run.

At each point the leading Floquet multipliers are computed. Between two points where the
number of multipliers outside the unit circle changes, the crossing is reported with its
kind: a real multiplier through ``+1`` (fold or pitchfork), through ``-1`` (period
doubling), a complex pair (Neimark-Sacker: a torus, quasi-periodic motion), with the
parameter value interpolated linearly in ``|mu| - 1``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.sparse.linalg import gmres

from knotmm.errors import ConfigError, SimulationFault
from knotmm.orbit.flow import rms
from knotmm.orbit.shooting import MAX_MOVE, Orbit, bordered_operator, residual, solve_orbit

__all__ = ["ContinuationPoint", "Bifurcation", "parse_range", "check_range",
           "continue_orbit", "find_bifurcations"]

log = logging.getLogger(__name__)

#: Keys that can be followed (``knot.beads`` step by step, the others by arclength).
CONTINUOUS_KEYS = ("model.bending_stiffness", "model.bond_stiffness", "model.gravity",
                   "model.lj_epsilon", "model.lj_sigma", "model.bond_length")
DISCRETE_KEYS = ("knot.beads",)


@dataclass
class ContinuationPoint:
    """One point of a branch.

    Attributes
    ----------
    value : float
        The parameter.
    orbit : knotmm.orbit.shooting.Orbit
    floquet : knotmm.orbit.floquet.FloquetResult or None
    """

    value: float
    orbit: Orbit
    floquet: object = None

    @property
    def moduli(self) -> np.ndarray:
        return np.array([]) if self.floquet is None else np.abs(self.floquet.multipliers)


@dataclass
class Bifurcation:
    """A multiplier crossing the unit circle between two points of the branch."""

    between: tuple
    value: float
    kind: str
    multiplier: complex
    notes: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"between": list(self.between), "parameter": self.value, "kind": self.kind,
                "multiplier_after": [self.multiplier.real, self.multiplier.imag]}


def parse_range(text: str) -> tuple[str, float, float]:
    """``"model.bending_stiffness=5:500"`` -> ``("model.bending_stiffness", 5.0, 500.0)``."""
    key, sep, span = str(text).partition("=")
    start, colon, stop = span.partition(":")
    known = CONTINUOUS_KEYS + DISCRETE_KEYS
    if not sep or not colon:
        raise ConfigError(
            f"--continue {text!r}: expected KEY=START:STOP, e.g. model.bending_stiffness=5:500"
        )
    if key.strip() not in known:
        raise ConfigError(f"--continue {text!r}: {key.strip()!r} cannot be followed; expected "
                          f"one of {', '.join(known)}")
    try:
        a, b = float(start), float(stop)
    except ValueError:
        raise ConfigError(f"--continue {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a == b:
        raise ConfigError(f"--continue {text!r}: START and STOP must be finite and differ")
    if key.strip() in DISCRETE_KEYS and not (a.is_integer() and b.is_integer()):
        raise ConfigError(f"--continue {text!r}: {key.strip()} takes whole numbers, e.g. "
                          f"{key.strip()}={math.floor(a)}:{math.ceil(b)}")
    return key.strip(), a, b


#: The smallest parameter step between two points, relative to ``max(1, |START|)``: ten
#: times the finite-difference step of ``dr/dp`` (``1e-6``), below which ``dr/dp`` is noise.
MIN_RELATIVE_STEP = 1e-5


def check_range(cfg, key: str, start: float, stop: float, points: int) -> None:
    """Check a continuation before any orbit is computed (one line, ConfigError).

    ``points`` must be an integer >= 2; START and STOP must be values the run file accepts
    for ``key`` (:meth:`knotmm.config.RunConfig.replace` validates them); a continuous
    range must be wider than ``points - 1`` steps of :data:`MIN_RELATIVE_STEP`.
    """
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise ConfigError(f"--points {points!r}: need an integer >= 2")
    text = f"--continue {key}={start:g}:{stop:g}"
    for value in (start, stop):
        try:
            cfg.replace({key: int(value) if key in DISCRETE_KEYS else float(value)})
        except ConfigError as exc:
            raise ConfigError(f"{text}: {value:g} is not a valid {key} ({exc})") from None
    if key not in DISCRETE_KEYS:
        step = abs(stop - start) / (points - 1)
        smallest = MIN_RELATIVE_STEP * max(1.0, abs(start))
        if step < smallest:
            raise ConfigError(
                f"{text} with --points {points}: steps of {step:.3g} are below the "
                f"{smallest:.3g} a continuation can resolve (dr/dp by finite differences); "
                f"widen the range or ask for fewer points"
            )


def _model(model, key: str, value: float):
    """``model`` (a :class:`knotmm.model.parameters.ChainModel`) with ``key`` (a
    ``model.*`` key of :data:`CONTINUOUS_KEYS`) at ``value``; ``knot.beads`` leaves it as
    it is (the model does not depend on the chain's size)."""
    table, name = key.split(".")
    if table != "model":
        return model
    return replace(model, **{name: float(value)})


def resample_ring(x: np.ndarray, n_new: int) -> np.ndarray:
    """A closed chain resampled to ``n_new`` beads, stretched by ``n_new / n`` (centred).

    Linear interpolation along the ring by arclength; shape (n_new, 3), in d.
    """
    n = x.shape[0]
    closed = np.vstack([x, x[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    targets = np.linspace(0.0, s[-1], n_new, endpoint=False)
    out = np.column_stack([np.interp(targets, s, closed[:, k]) for k in range(3)])
    c = out.mean(axis=0)
    return (out - c) * (n_new / n)


def _arclength_newton(make_flow, model, key, u1, tangent, ds, scale, tolerance,
                      max_iterations=15, gmres_tolerance=1e-4):
    """Solve the orbit condition plus ``<U - U_pred, tau> = 0``; return (Orbit, value) or None."""
    x1, t1, th1, p1 = u1
    n3 = x1.size
    pred = np.concatenate([x1.ravel(), [t1, th1, p1]]) + ds * tangent / scale
    x = pred[:n3].reshape(x1.shape)
    period, rotation, value = pred[n3], pred[n3 + 1], pred[n3 + 2]
    history = []
    step_h = None  # one fixed step for the whole solve: the map must not change under Newton
    for it in range(1, max_iterations + 1):
        flow = make_flow(_model(model, key, value), x, step_h)
        step_h = flow.timestep
        r, end = residual(flow, x, period, rotation)
        arc = float((np.concatenate([x.ravel(), [period, rotation, value]]) - pred) * scale
                    @ tangent)
        res = rms(r)
        history.append(res)
        if res <= tolerance and abs(arc) <= 1e-6:
            orbit = Orbit(x, period, rotation, end.mean(axis=0) - x.mean(axis=0), res, True,
                          it - 1, history, "converged", flow.n_flows, flow.timestep)
            return orbit, value, flow
        dp = 1e-6 * max(1.0, abs(value))
        r_p, _ = residual(make_flow(_model(model, key, value + dp), x, step_h), x, period,
                          rotation)
        col_p = ((r_p - r) / dp).ravel()
        op = bordered_operator(flow, x, period, rotation, end, column=col_p,
                               row=tangent * scale)
        rhs = np.concatenate([-r.ravel(), [0.0, 0.0, -arc]])
        du, _ = gmres(op, rhs, rtol=gmres_tolerance, atol=0.0, restart=200, maxiter=1)
        largest = float(np.max(np.linalg.norm(du[:n3].reshape(x.shape), axis=1)))
        step = min(1.0, MAX_MOVE / largest) if largest > 0 else 1.0
        x = x + step * du[:n3].reshape(x.shape)
        period += step * du[n3]
        rotation += step * du[n3 + 1]
        value += step * du[n3 + 2]
        if not period > 0:
            return None
    return None


def continue_orbit(orbit, model, key, start, stop, make_flow, points=8, modes=10,
                   tolerance=1e-8, floquet_fn=None, on_point=None, branch=None):
    """Follow ``orbit`` (converged for ``model``) from ``key = start`` to ``stop``.

    Parameters
    ----------
    orbit : Orbit
        A converged orbit (a guess for the first point, at ``key = start``).
    model : knotmm.model.parameters.ChainModel
        The run's model (its plan's, :class:`knotmm.plan.PlanParts`); each point's is this
        one with ``key`` at the point's value.
    key : str
        See :data:`CONTINUOUS_KEYS`, :data:`DISCRETE_KEYS`.
    start, stop : float
    make_flow : callable
        ``make_flow(model, positions, timestep=None) -> FlowMap`` (``None``: a stable step
        chosen at ``positions``).
    points : int
        Points asked for along ``start .. stop`` (the arclength step is set from it).
    modes : int
        Floquet multipliers per point (0: none).
    tolerance : float
        Newton's residual, d rms per bead.
    floquet_fn : callable, optional
        ``floquet_fn(flow, orbit, k)``; default :func:`knotmm.orbit.floquet.floquet`.
    on_point : callable, optional
        Called with each new :class:`ContinuationPoint` (progress, partial output).
    branch : list of ContinuationPoint, optional
        Points already found by an interrupted continuation with the same arguments: it
        goes on after them, as it would have (``orbit`` may then be None).

    Returns
    -------
    list of ContinuationPoint
        In the order found (``branch``'s first); stops at ``stop``, at a failed Newton
        solve, or after ``3 * points`` points past the first two.
    """
    from knotmm.orbit.floquet import floquet as default_floquet

    floquet_fn = floquet_fn or default_floquet
    if points < 2:
        raise ConfigError(f"--points {points!r}: need at least 2")
    branch = list(branch or [])
    done = len(branch)

    def add(value, orb, flow):
        res = floquet_fn(flow, orb, min(modes, orb.positions.size - 8)) if modes else None
        point = ContinuationPoint(float(value), orb, res)
        branch.append(point)
        if on_point is not None:
            on_point(point)

    discrete = key in DISCRETE_KEYS
    values = np.linspace(start, stop, points)
    if discrete:
        values = np.unique(np.round(values).astype(int))
    if len(values) < 2:
        raise ConfigError(f"--continue {key}={start:g}:{stop:g}: the range holds a single "
                          f"value of {key}; give two that differ")
    first = values[0]
    current = branch[-1].orbit if branch else orbit
    step_p = values[1] - values[0]
    if discrete:
        for value in values[done:]:
            found = _orbit_at_beads(current, model, int(value), make_flow, tolerance)
            if found is None:
                break
            current, flow = found
            add(value, current, flow)
        return branch
    for value in (first, first + step_p)[done:]:
        try:
            flow = make_flow(_model(model, key, value), current.positions)
            current = solve_orbit(flow, current.positions, current.period, current.rotation,
                                  tolerance=tolerance)
        except SimulationFault as exc:
            log.info("continuation: lost the orbit at %s = %g: %s", key, value, exc)
            return branch
        if not current.converged:
            return branch
        add(value, current, flow)
    direction = math.copysign(1.0, stop - start)
    for _ in range(3 * points - max(0, done - 2)):
        if (branch[-1].value - stop) * direction >= -1e-2 * abs(step_p):
            break  # at STOP (within a hundredth of a step) or past it
        a, b = branch[-2], branch[-1]
        ua = np.concatenate([a.orbit.positions.ravel(), [a.orbit.period, a.orbit.rotation,
                                                         a.value]])
        ub = np.concatenate([b.orbit.positions.ravel(), [b.orbit.period, b.orbit.rotation,
                                                         b.value]])
        # scale each block so the parameter and the shape weigh alike in the arclength
        scale = np.ones_like(ua)
        scale[-1] = 1.0 / abs(step_p)
        diff = (ub - ua) * scale
        ds = float(np.linalg.norm(diff))
        tangent = diff / ds
        dp_pred = ds * tangent[-1] / scale[-1]
        if dp_pred * direction > 0 and (b.value + dp_pred - stop) * direction > 0:
            ds *= (stop - b.value) / dp_pred  # the predictor lands on stop
        try:
            found = _arclength_newton(
                make_flow, model, key,
                (b.orbit.positions, b.orbit.period, b.orbit.rotation, b.value),
                tangent, ds, scale, tolerance)
        except SimulationFault as exc:
            log.info("continuation: the chain broke after %s = %g: %s", key, b.value, exc)
            found = None
        if found is None:
            log.info("continuation: Newton failed after %s = %g", key, b.value)
            break
        orb, value, flow = found
        add(value, orb, flow)
    return branch


def _orbit_at_beads(orbit, model, n_new, make_flow, tolerance):
    """(Orbit, FlowMap) at another number of beads, from ``orbit`` resampled; None if lost."""
    from knotmm.orbit.start import refine_guess

    n = orbit.positions.shape[0]
    x = orbit.positions if n_new == n else resample_ring(orbit.positions, n_new)
    try:
        flow = make_flow(model, x)
        period, rotation = orbit.period, orbit.rotation
        if n_new != n:
            period, rotation, _ = refine_guess(flow, x, orbit.period * n_new / n)
        found = solve_orbit(flow, x, period, rotation, tolerance=tolerance)
    except SimulationFault:
        return None
    if not found.converged:
        return None
    return found, flow


def find_bifurcations(branch, discrete: bool = False) -> list[Bifurcation]:
    """Crossings of the unit circle between consecutive points (see the module's text).

    With ``discrete`` (``knot.beads``) there is no crossing point between two neighbouring
    values: a change is reported as such, at the second value, without a kind.
    """
    out = []
    for a, b in zip(branch, branch[1:], strict=False):
        if a.floquet is None or b.floquet is None:
            continue
        na, nb = a.floquet.n_unstable, b.floquet.n_unstable
        if na == nb:
            continue
        mult = b.floquet.multipliers
        # the multiplier that crossed: the one of b closest to the unit circle
        k = int(np.argmin(np.abs(np.abs(mult) - 1.0)))
        mu = complex(mult[k])
        ma = np.abs(a.floquet.multipliers)
        ka = int(np.argmin(np.abs(ma - 1.0)))
        fa, fb = abs(ma[ka]) - 1.0, abs(mu) - 1.0
        value = a.value + (b.value - a.value) * fa / (fa - fb) if fa != fb else b.value
        if discrete:
            direction = "loses" if nb > na else "gains"
            out.append(Bifurcation(
                (a.value, b.value), float(b.value),
                f"change of stability between {a.value:g} and {b.value:g} (a discrete "
                f"parameter: no crossing point in between)", mu,
                [f"the orbit {direction} stability ({na} -> {nb} unstable)"]))
            continue
        if abs(mu.imag) > 1e-6 * abs(mu):
            angle = abs(math.atan2(mu.imag, mu.real))
            kind = (f"Neimark-Sacker (complex pair at angle +-{angle:.3g} rad: a torus, "
                    "quasi-periodic motion)")
        elif mu.real > 0:
            kind = "fold or pitchfork (real multiplier through +1)"
        else:
            kind = "period doubling (real multiplier through -1)"
        direction = "loses" if nb > na else "gains"
        out.append(Bifurcation((a.value, b.value), float(value), kind, mu,
                               [f"the orbit {direction} stability ({na} -> {nb} unstable)"]))
    return out
