"""The analysis.json keys of the regime checks (issue 13) and small helpers of the pipeline.

:func:`regime_keys` turns a :class:`knotmm.analysis.regimes.Regime` (and the vortex-knot fit)
into the keys documented in the README ("analysis.json: regimes, body frame, uncertainties").
"""

from __future__ import annotations

import math

import numpy as np

from knotmm.analysis.bootstrap import bootstrap_uncertainties
from knotmm.analysis.regimes import TOROIDAL_WINDOW, Regime

__all__ = [
    "R2_MIN",
    "TIME_AXIS",
    "body_fit_coordinates",
    "regime_keys",
    "shared_knot_cache",
    "single_threaded_blas",
    "tilt_row",
]

#: A coordinate whose vortex-knot R^2 is below this gets a note: the formula fits it badly.
R2_MIN = 0.5

#: Where the times come from (``time_axis`` in analysis.json).
TIME_AXIS = (
    "t = frame index x frame_interval: mdtraj reads a DCD's time as the frame index, so the "
    "interval comes from run.toml ([output] frame_interval) or --frame-interval"
)


def shared_knot_cache():
    """An ``identify`` for :func:`knotmm.analysis.knot_types.knot_types` that remembers frames.

    The scan for a change of knot type and the identification at the window's ends check
    mostly the same frames; with one memo each frame is identified once.
    """
    from knotmm.analysis.knot_types import identify_signed

    memo: dict[bytes, str | None] = {}

    def identify(x: np.ndarray) -> str | None:
        key = np.ascontiguousarray(x).tobytes()
        if key not in memo:
            memo[key] = identify_signed(x)
        return memo[key]

    return identify


def body_fit_coordinates(body, sel: slice):
    """``rho``, ``alpha``, ``z_lab`` for :func:`knotmm.analysis.fit.fit_vortex_knot`, body frame.

    ``rho`` and ``alpha`` about the torus axis through the centroid; the height is the
    centroid's lab height plus the height above the mean plane, so V is the fall of the
    centroid and the swirl is measured along the torus axis. For a horizontal torus these
    are the lab coordinates.

    Returns
    -------
    tuple of ndarray, each shape (n_frames, n_beads)
    """
    return body.rho[sel], body.phi[sel], body.z[sel] + body.centroid[sel, 2:3]


def _fit_notes(fit, amp_rho: float, amp_z: float, p: int, q: int | None) -> list[str]:
    if fit is None:
        return []
    bad = [c for c in ("rho", "alpha", "z") if not fit.r2.get(c, 1.0) >= R2_MIN]
    if not bad:
        return []
    r2 = ", ".join(f"R^2({c}) = {fit.r2[c]:.3g}" for c in bad)
    text = f"the vortex-knot formula fits badly ({r2} < {R2_MIN:g})"
    if q:
        k = math.hypot(p, q) / q
        text += (
            f"; the orbit's half-amplitudes are {amp_rho:.3g} d in rho and {amp_z:.3g} d "
            f"in z (z/rho = {amp_z / amp_rho:.3g}), the formula's ratio is k = {k:.3g}"
            if amp_rho > 0
            else ""
        )
    return [text]


def regime_keys(
    regime: Regime, fit, p: int, q: int | None, notes: list, body_swirl, body_rot
) -> dict:
    """The new analysis.json keys; appends the fit-quality note to ``notes``.

    Parameters
    ----------
    regime : Regime
    fit : VortexFit or None
    p, q : int
        The torus knot used by the fit (q may be None).
    notes : list of str
        Extended in place.
    body_swirl, body_rot : Spectrum
        Swirl and rotation spectra of the window in the body frame.

    Returns
    -------
    dict
        ``swirl_detected``, ``swirl_detection``, ``tau_swirl_body``, ``tau_rot_body`` (each
        with ``_uncertainty``), ``rotation_frequency_body``,
        ``swirl_amplitude_rho``, ``swirl_amplitude_z``, ``torus_fraction``,
        ``torus_fraction_window``, ``toroidal_window``, ``body_frame``, ``uncertainties``,
        ``time_axis``.
    """
    body, det, win = regime.body, regime.detection, regime.window
    sel = win.frames
    tau_body = tau_body_err = amp_rho = amp_z = float("nan")
    if det.detected:
        tau_body, tau_body_err = body_swirl.peak.period, body_swirl.peak.period_uncertainty
        amp_rho, amp_z = det.amplitude_rho, det.amplitude_z
        notes += _fit_notes(fit, amp_rho, amp_z, p, q)
    return {
        "swirl_detected": det.detected,
        "swirl_detection": det.to_dict(),
        "tau_swirl_body": tau_body,
        "tau_swirl_body_uncertainty": tau_body_err,
        "tau_rot_body": body_rot.peak.period,
        "tau_rot_body_uncertainty": body_rot.peak.period_uncertainty,
        "rotation_frequency_body": body_rot.peak.frequency,
        "swirl_amplitude_rho": amp_rho,
        "swirl_amplitude_z": amp_z,
        "torus_fraction": regime.summary["torus_fraction"],
        "torus_fraction_window": regime.summary["torus_fraction_window"],
        "toroidal_window": regime.toroidal,
        "toroidal_window_threshold": TOROIDAL_WINDOW,
        "body_frame": regime.summary,
        "uncertainties": bootstrap_uncertainties(body, sel, swirl=det.detected),
        "time_axis": TIME_AXIS,
    }


def tilt_row(d: dict) -> str | None:
    """The "torus axis vs gravity" line of :func:`knotmm.analysis.result.format_table`.

    From the body-frame summary (the normal followed continuously), over the window and the
    whole run, saying when the torus tilts after the window.
    """
    b = d.get("body_frame")
    if not b:
        return None
    text = (
        f"median tilt {b['window_inclination_median_deg']:.3g} deg in the window, "
        f"{b['inclination_median_deg']:.3g} over the run (max {b['inclination_max_deg']:.3g})"
    )
    if b["tilts_after_window"]:
        text += f"; tilts after the window, up to {b['after_window_inclination_max_deg']:.3g} deg"
    text += (
        f"; {b['flips']['count']} flips; flat torus {100 * b['torus_fraction']:.0f}% of "
        f"frames ({100 * b['torus_fraction_window']:.0f}% in the window)"
    )
    return text


def single_threaded_blas(func):
    """Decorator: run ``func`` with BLAS limited to one thread.

    The analysis multiplies small matrices (a few hundred rows); a multi-threaded BLAS gains
    nothing there and, on a busy machine, spends its time spin-waiting: ``numpy.linalg.pinv``
    of a 186 x 186 matrix took 1-2 s with 2 OpenBLAS threads under load, 0.04 s with one.
    """
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper
