"""Fit of the vortex-knot formula to every bead, and the scaled coordinates.

The model (docs/model.md, "Observables"), with the time ``s = t - t0`` counted from the window
start, the swirl angle ``theta_i = 2 pi s / tau_swirl + phi_i`` and ``k = sqrt(p^2+q^2)/q``:

    rho_i(s)   = rho0 + C sin(theta_i)
    alpha_i(s) = a_i + s_alpha C p / (q rho0) cos(theta_i) + 2 pi s / tau_rot
    z_i(s)     = z0 - V s + s_z C k cos(theta_i)

Shared: rho0, C, tau_swirl, tau_rot (signed: negative is clockwise seen from above), V
(positive when falling) and the height z0 of the centre of mass at the window start; per
bead: the swirl phase phi_i and the azimuth a_i. The signs ``s_z`` and ``s_alpha`` (+1 in the
formula as written) are read off the data before the fit: the mirror image of a knot, or a
swirl turning the other way, flips them. rho and alpha are about the vertical axis through
the centre of mass; z is the lab height.

Residuals are lengths (alpha residuals are multiplied by the mean radius), minimised with
``scipy.optimize.least_squares`` (trust region, sparse analytic Jacobian). Quality: for
each coordinate, the fraction of the variance of its oscillation (data minus the fitted
mean motion) that the fitted swirl explains (R^2), and the rms residual in d.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares

__all__ = ["VortexFit", "fit_vortex_knot", "scaled_coordinates", "ScaledCoordinates"]

logger = logging.getLogger(__name__)

_SHARED = ("rho0", "C", "nu_swirl", "nu_rot", "V", "z0")
_MAX_FRAMES = 600


@dataclass
class VortexFit:
    """Result of the vortex-knot fit.

    Attributes
    ----------
    rho0, swirl_amplitude : float
        Major radius and swirl amplitude C, in d.
    tau_swirl : float
        Swirl period, in tau_d (positive).
    tau_rot : float
        Rotation period, in tau_d; negative for a clockwise rotation seen from above.
    velocity : float
        Sedimentation speed V, in d/tau_d (positive when falling).
    z0 : float
        Centre-of-mass height at the window start, in d.
    t0 : float
        Window start (time origin of the phases), in tau_d.
    phases, azimuths : ndarray, shape (n_beads,)
        Per-bead swirl phase phi_i (in [0, 2 pi)) and azimuth a_i, in rad.
    p, q : int
        The torus knot used in the formula.
    sign_z, sign_alpha : int
        Orientation signs ``s_z`` and ``s_alpha`` (+1 in the formula as written).
    errors : dict
        Standard errors of the shared parameters (from the Jacobian, assuming independent
        residuals, so a lower bound), same units as the parameters.
    r2 : dict
        Fraction of the oscillation variance explained: ``rho``, ``alpha``, ``z``, ``total``.
    rms : dict
        Rms residual per coordinate and in total, in d (alpha as arc length).
    converged : bool
        Whether the optimiser reported convergence.
    message : str
        The optimiser's message.
    n_points : int
        Number of residuals fitted.
    """

    rho0: float
    swirl_amplitude: float
    tau_swirl: float
    tau_rot: float
    velocity: float
    z0: float
    t0: float
    phases: np.ndarray
    azimuths: np.ndarray
    p: int
    q: int
    sign_z: int = 1
    sign_alpha: int = 1
    errors: dict = field(default_factory=dict)
    r2: dict = field(default_factory=dict)
    rms: dict = field(default_factory=dict)
    converged: bool = True
    message: str = ""
    n_points: int = 0

    def to_dict(self) -> dict:
        """JSON-ready summary (without the per-bead phases)."""
        return {
            "rho0": self.rho0,
            "swirl_amplitude": self.swirl_amplitude,
            "tau_swirl": self.tau_swirl,
            "tau_rot": self.tau_rot,
            "sedimentation_velocity": self.velocity,
            "z0": self.z0,
            "t0": self.t0,
            "p": self.p,
            "q": self.q,
            "sign_z": self.sign_z,
            "sign_alpha": self.sign_alpha,
            "errors": self.errors,
            "r2": self.r2,
            "rms": self.rms,
            "rms_over_amplitude": self.rms.get("total", float("nan")) / self.swirl_amplitude
            if self.swirl_amplitude
            else None,
            "converged": self.converged,
            "message": self.message,
            "n_points": self.n_points,
        }


def _model(params, s, p, q, sz, sa, n):
    rho0, c, nu_sw, nu_rot, v, z0 = params[:6]
    phi, a = params[6 : 6 + n], params[6 + n :]
    theta = 2.0 * np.pi * nu_sw * s[:, None] + phi[None, :]
    k = np.sqrt(p * p + q * q) / q
    rho = rho0 + c * np.sin(theta)
    alpha = a[None, :] + sa * c * p / (q * rho0) * np.cos(theta) + 2.0 * np.pi * nu_rot * s[:, None]
    z = (z0 - v * s)[:, None] + sz * c * k * np.cos(theta)
    return rho, alpha, z, theta


def _pattern(m: int, n: int):
    """Row and column indices of the Jacobian's non-zeros (fixed pattern)."""
    base = np.arange(m * n)  # residual index within a block: frame * n + bead
    bead = base % n
    rows, cols = [], []

    def add(block: int, col):
        rows.append(block * m * n + base)
        cols.append(np.broadcast_to(col, base.shape))

    for shared in (0, 1, 2):  # rho: rho0, C, nu_swirl
        add(0, shared)
    add(0, 6 + bead)  # phi
    for shared in (0, 1, 2, 3):  # alpha: rho0, C, nu_swirl, nu_rot
        add(1, shared)
    add(1, 6 + bead)
    add(1, 6 + n + bead)  # a
    for shared in (1, 2, 4, 5):  # z: C, nu_swirl, V, z0
        add(2, shared)
    add(2, 6 + bead)
    return np.concatenate(rows), np.concatenate(cols)


def _jacobian_values(params, s, p, q, sz, sa, n, w):
    rho0, c = params[0], params[1]
    _, _, _, theta = _model(params, s, p, q, sz, sa, n)
    sin, cos = np.sin(theta).ravel(), np.cos(theta).ravel()
    ts = np.repeat(2.0 * np.pi * s, n)
    k = np.sqrt(p * p + q * q) / q
    g = sa * p / (q * rho0)  # alpha amplitude per unit C
    one = np.ones_like(sin)
    vals = [
        -one,
        -sin,
        -c * cos * ts,
        -c * cos,  # rho
        w * g * c / rho0 * cos,
        -w * g * cos,
        w * g * c * sin * ts,
        -w * ts,  # alpha shared
        w * g * c * sin,
        -w * one,  # alpha: phi, a
        -sz * k * cos,
        sz * c * k * sin * ts,
        np.repeat(s, n),
        -one,  # z shared
        sz * c * k * sin,  # z: phi
    ]
    return np.concatenate(vals)


def _orientation(s, drho, dalpha, dz, nu):
    """Signs s_z, s_alpha from the phase of z and alpha relative to rho at the swirl line."""
    demod = np.exp(-2j * np.pi * nu * s)[:, None]
    a_rho = (drho * demod).sum(axis=0)
    a_z = (dz * demod).sum(axis=0)
    a_alpha = (dalpha * demod).sum(axis=0)
    # rho = C sin(theta), z = s_z C k cos(theta)  =>  a_z / a_rho = i s_z k
    sign_z = 1 if np.imag((a_z * np.conj(a_rho)).sum()) >= 0 else -1
    sign_alpha = 1 if np.imag((a_alpha * np.conj(a_rho)).sum()) >= 0 else -1
    phases = np.angle(1j * a_rho)  # a_rho = C e^{i phi} / (2i)
    return sign_z, sign_alpha, np.mod(phases, 2.0 * np.pi)


def fit_vortex_knot(
    times,
    rho,
    alpha,
    z_lab,
    p: int,
    q: int,
    tau_swirl: float,
    tau_rot: float,
    max_frames: int = _MAX_FRAMES,
) -> VortexFit:
    """Fit the vortex-knot formula to every bead of a steady window.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Times of the window's frames, in tau_d.
    rho, alpha : ndarray, shape (n_frames, n_beads)
        Cylindrical radius (d) and unwrapped azimuth (rad) about the vertical axis through
        the centre of mass.
    z_lab : ndarray, shape (n_frames, n_beads)
        Bead heights in the lab frame, in d.
    p, q : int
        The torus knot T(p, q) of the formula.
    tau_swirl, tau_rot : float
        Starting guesses, in tau_d (``tau_rot`` signed: negative is clockwise); the
        spectral estimates.
    max_frames : int
        Frames beyond this are thinned evenly (the fit cost grows with frames x beads).

    Returns
    -------
    VortexFit
    """
    t = np.asarray(times, dtype=np.float64)
    step = max(1, int(np.ceil(len(t) / max_frames)))
    sel = slice(None, None, step)
    t0 = float(t[0])
    s = t[sel] - t0
    rho_d, alpha_d, z_d = (np.asarray(a, dtype=np.float64)[sel] for a in (rho, alpha, z_lab))
    m, n = rho_d.shape

    # starting values from simple averages
    nu_sw = 1.0 / abs(tau_swirl)
    nu_rot = 1.0 / tau_rot if np.isfinite(tau_rot) and tau_rot != 0 else 0.0
    z_com = z_d.mean(axis=1)
    slope, z0 = np.polyfit(s, z_com, 1)
    rho0 = float(rho_d.mean())
    a0 = (alpha_d - 2.0 * np.pi * nu_rot * s[:, None]).mean(axis=0)
    drho = rho_d - rho_d.mean(axis=0)
    dz = z_d - z_com[:, None]
    dalpha = alpha_d - a0[None, :] - 2.0 * np.pi * nu_rot * s[:, None]
    sign_z, sign_alpha, phases = _orientation(s, drho, dalpha, dz, nu_sw)
    c0 = float(np.sqrt(2.0 * np.mean(drho**2)))
    x0 = np.concatenate([[rho0, c0, nu_sw, nu_rot, -slope, z0], phases, a0])

    w = rho0  # alpha residuals as arc length
    rows, cols = _pattern(m, n)
    shape = (3 * m * n, 6 + 2 * n)

    def residuals(params):
        r_m, a_m, z_m, _ = _model(params, s, p, q, sign_z, sign_alpha, n)
        return np.concatenate(
            [(rho_d - r_m).ravel(), (w * (alpha_d - a_m)).ravel(), (z_d - z_m).ravel()]
        )

    def jacobian(params):
        vals = _jacobian_values(params, s, p, q, sign_z, sign_alpha, n, w)
        return sp.csr_matrix((vals, (rows, cols)), shape=shape)

    res = least_squares(
        residuals,
        x0,
        jac=jacobian,
        method="trf",
        tr_solver="lsmr",
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-10,
        max_nfev=200,
    )
    params = res.x.copy()
    if params[1] < 0:  # C < 0 is C > 0 with every phase shifted by pi
        params[1] = -params[1]
        params[6 : 6 + n] += np.pi
    if params[2] < 0:  # a negative swirl frequency: mirror the swirl angle
        params[2] = -params[2]
        params[6 : 6 + n] = np.pi - params[6 : 6 + n]
        sign_z, sign_alpha = -sign_z, -sign_alpha
    params[6 : 6 + n] = np.mod(params[6 : 6 + n], 2.0 * np.pi)

    # quality: variance of the oscillations explained by the swirl terms
    r_m, a_m, z_m, theta = _model(params, s, p, q, sign_z, sign_alpha, n)
    mean_rho = params[0]
    mean_alpha = params[6 + n :][None, :] + 2.0 * np.pi * params[3] * s[:, None]
    mean_z = (params[5] - params[4] * s)[:, None]
    parts = {
        "rho": (rho_d - mean_rho, rho_d - r_m),
        "alpha": (w * (alpha_d - mean_alpha), w * (alpha_d - a_m)),
        "z": (z_d - mean_z, z_d - z_m),
    }
    r2, rms = {}, {}
    tot_osc = tot_res = 0.0
    for name, (osc, resid) in parts.items():
        ss_osc, ss_res = float((osc**2).sum()), float((resid**2).sum())
        r2[name] = 1.0 - ss_res / ss_osc if ss_osc > 0 else float("nan")
        rms[name] = float(np.sqrt(ss_res / resid.size))
        tot_osc += ss_osc
        tot_res += ss_res
    r2["total"] = 1.0 - tot_res / tot_osc if tot_osc > 0 else float("nan")
    rms["total"] = float(np.sqrt(tot_res / (3 * m * n)))

    errors = _shared_errors(res, shape)
    nu_sw_fit, nu_rot_fit = params[2], params[3]
    tau_sw = 1.0 / nu_sw_fit
    tau_r = 1.0 / nu_rot_fit if nu_rot_fit != 0 else float("inf")
    errs = {
        "rho0": errors[0],
        "swirl_amplitude": errors[1],
        "tau_swirl": errors[2] / nu_sw_fit**2,
        "tau_rot": errors[3] / nu_rot_fit**2 if nu_rot_fit != 0 else float("inf"),
        "sedimentation_velocity": errors[4],
        "z0": errors[5],
    }
    if not res.success:
        logger.warning("vortex-knot fit did not converge: %s", res.message)
    return VortexFit(
        rho0=float(params[0]),
        swirl_amplitude=float(params[1]),
        tau_swirl=float(tau_sw),
        tau_rot=float(tau_r),
        velocity=float(params[4]),
        z0=float(params[5]),
        t0=t0,
        phases=params[6 : 6 + n],
        azimuths=params[6 + n :],
        p=int(p),
        q=int(q),
        sign_z=int(sign_z),
        sign_alpha=int(sign_alpha),
        errors={k: float(v) for k, v in errs.items()},
        r2=r2,
        rms=rms,
        converged=bool(res.success),
        message=str(res.message),
        n_points=int(3 * m * n),
    )


def _shared_errors(res, shape) -> np.ndarray:
    """Standard errors of the six shared parameters from J^T J (residuals independent)."""
    jac = res.jac
    jtj = (jac.T @ jac).toarray() if sp.issparse(jac) else jac.T @ jac
    dof = max(shape[0] - shape[1], 1)
    sigma2 = 2.0 * res.cost / dof
    cov = np.linalg.pinv(jtj) * sigma2
    return np.sqrt(np.clip(np.diag(cov)[:6], 0.0, None))


@dataclass
class ScaledCoordinates:
    """Coordinates that collapse every bead onto one curve.

    Attributes
    ----------
    cycle : ndarray, shape (n_frames, n_beads)
        ``(t - t0) / tau_swirl + phi_i / (2 pi)``: the swirl angle in turns.
    rho : ndarray, shape (n_frames, n_beads)
        ``(rho - rho0) / C``; the formula predicts ``sin(2 pi cycle)``.
    alpha : ndarray, shape (n_frames, n_beads)
        ``s_alpha (q rho0 / p)(alpha - a_i - 2 pi (t - t0)/tau_rot) / C``; predicts
        ``cos(2 pi cycle)``.
    z : ndarray, shape (n_frames, n_beads)
        ``s_z q / sqrt(p^2 + q^2) (z - z0 + V (t - t0)) / C``; predicts ``cos(2 pi cycle)``.
    """

    cycle: np.ndarray
    rho: np.ndarray
    alpha: np.ndarray
    z: np.ndarray


def scaled_coordinates(fit: VortexFit, times, rho, alpha, z_lab) -> ScaledCoordinates:
    """Scale bead coordinates with the fitted parameters (docs/model.md's collapse).

    Parameters
    ----------
    fit : VortexFit
    times : ndarray, shape (n_frames,)
        In tau_d.
    rho, alpha, z_lab : ndarray, shape (n_frames, n_beads)
        As given to :func:`fit_vortex_knot`.

    Returns
    -------
    ScaledCoordinates
    """
    s = np.asarray(times, dtype=np.float64)[:, None] - fit.t0
    p, q, c, r0 = fit.p, fit.q, fit.swirl_amplitude, fit.rho0
    cycle = s / fit.tau_swirl + fit.phases[None, :] / (2.0 * np.pi)
    rot = 2.0 * np.pi * s / fit.tau_rot if np.isfinite(fit.tau_rot) else 0.0
    x_rho = (np.asarray(rho) - r0) / c
    x_alpha = fit.sign_alpha * (q * r0 / p) * (np.asarray(alpha) - fit.azimuths - rot) / c
    x_z = fit.sign_z * q / np.hypot(p, q) * (np.asarray(z_lab) - fit.z0 + fit.velocity * s) / c
    return ScaledCoordinates(cycle, x_rho, x_alpha, x_z)
