"""Body-frame analysis: the torus normal followed in time, body cylindrical coordinates, shape.

The lab-frame observables (:mod:`knotmm.analysis.geometry`) assume a horizontal torus whose
axis is the vertical. When the torus tilts or turns over they mix its tumbling with its
swirl. Here every frame is described about its own axis (docs/model.md, "Observables").

Torus normal
    The eigenvector ``n`` of the smallest eigenvalue ``g1`` of the gyration tensor
    ``G = (1/N) sum_i (r_i - r_c)(r_i - r_c)^T`` (``r_c`` the centroid; eigenvalues
    ``g1 <= g2 <= g3``, in d^2). An eigenvector has no sign: the sign is *followed
    continuously*, ``n(t) . n(t - dt) >= 0``, starting from ``n(0)`` pointing up
    (``n_z >= 0``). A flip of the torus is then a crossing of 90 degrees by the angle
    between ``n`` and ``+z`` (counted with :func:`knotmm.analysis.tilt.find_flips`, 30 degree
    hysteresis). Following assumes the normal turns by less than 90 degrees between frames;
    :attr:`BodyFrame.max_turn_deg` reports the largest turn.

Body cylindrical coordinates
    About the line through the centroid along ``n``: ``z_b = (r - r_c) . n`` (height above
    the mean plane), ``rho_b`` the distance from that line, ``phi_b`` the azimuth measured
    from an in-plane reference direction that is parallel-transported from frame to frame
    (no twist about ``n``), unwrapped in time. For a horizontal torus ``n = +z`` and these
    are the lab coordinates; for any rigid motion ``rho_b`` and ``z_b`` are constant.

Flat-torus criterion (:data:`TORUS_CRITERION`), all four per frame:

* flat: ``g1 / g2 <= 0.25`` (a torus knot of major radius rho0 and swirl amplitude C has
  ``g1/g2 ~ (C k / rho0)^2``, about 0.02 for T(2,3) at N = 90; a random coil ~0.4);
* round: ``g2 / g3 >= 0.6`` (two nearly equal large moments; 1 for a symmetric torus knot);
* a hole: at most 5 % of the beads closer to the axis than half the median ``rho_b``;
* planar winding: ``|A . n| / (pi (g2 + g3)) >= 0.9`` with ``A`` the chain's area vector (about
  p for T(p, q), 1 for a circle, 0.998 for a 60-gon; see :mod:`knotmm.analysis.tilt`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from knotmm.analysis.tilt import Flips, find_flips

__all__ = [
    "BodyFrame",
    "TORUS_CRITERION",
    "body_frame",
    "inclination_summary",
    "torus_shape",
]

#: Thresholds of the flat-torus criterion (see the module docstring).
TORUS_CRITERION = {
    "max_flatness": 0.25,  # g1 / g2
    "min_roundness": 0.6,  # g2 / g3
    "hole_radius": 0.5,  # of the median rho_b
    "max_hole_fraction": 0.05,
    "min_winding": 0.9,
}

#: Inclination (degrees) above which a torus counts as tilted in the summaries.
TILTED_DEG = 30.0


@dataclass(frozen=True)
class BodyFrame:
    """Per-frame torus axis, shape descriptors and body cylindrical coordinates.

    Attributes
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    centroid : ndarray, shape (n_frames, 3)
        In d.
    normal : ndarray, shape (n_frames, 3)
        Unit torus normal, sign followed continuously (module docstring).
    moments : ndarray, shape (n_frames, 3)
        Gyration eigenvalues ``g1 <= g2 <= g3``, in d^2.
    rho, phi, z : ndarray, shape (n_frames, n_beads)
        Body cylindrical coordinates: distance from the axis (d), azimuth about ``n``
        (rad, unwrapped in time), height above the mean plane (d).
    winding : ndarray, shape (n_frames,)
        Planar winding ``(A . n) / (pi (g2 + g3))`` (signed by the followed normal).
    hole_fraction : ndarray, shape (n_frames,)
        Fraction of beads closer to the axis than half the frame's median ``rho``.
    toroidal : ndarray of bool, shape (n_frames,)
        The flat-torus criterion.
    tilt : ndarray, shape (n_frames,)
        Angle between the followed normal and ``+z``, degrees, 0..180.
    inclination : ndarray, shape (n_frames,)
        ``min(tilt, 180 - tilt)``: inclination of the axis, degrees, 0..90.
    flips : Flips
        Crossings of 90 degrees by ``tilt``.
    max_turn_deg : float
        Largest turn of the normal between consecutive frames, degrees.
    """

    times: np.ndarray
    centroid: np.ndarray
    normal: np.ndarray
    moments: np.ndarray
    rho: np.ndarray
    phi: np.ndarray
    z: np.ndarray
    winding: np.ndarray
    hole_fraction: np.ndarray
    toroidal: np.ndarray
    tilt: np.ndarray
    inclination: np.ndarray
    flips: Flips
    max_turn_deg: float


def _follow(vectors: np.ndarray) -> np.ndarray:
    """Flip signs so that consecutive unit vectors have a non-negative dot product."""
    v = vectors.copy()
    if v[0, 2] < 0:
        v[0] = -v[0]
    dots = np.einsum("fi,fi->f", v[1:], v[:-1])
    # flipping frame k flips the reference of frame k+1: the sign is a running product
    signs = np.r_[1.0, np.cumprod(np.where(dots < 0, -1.0, 1.0))]
    return v * signs[:, None]


def _reference(normal: np.ndarray) -> np.ndarray:
    """In-plane unit vectors parallel-transported along the normals, shape (n_frames, 3)."""
    n = normal
    e = np.empty_like(n)
    start = np.array([1.0, 0.0, 0.0]) if abs(n[0, 0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    cur = start - (start @ n[0]) * n[0]
    for k in range(len(n)):
        cur = cur - (cur @ n[k]) * n[k]
        norm = np.linalg.norm(cur)
        if norm < 1e-12:  # the normal swung onto the reference: take any perpendicular
            cur = np.cross(n[k], [0.0, 0.0, 1.0] if abs(n[k, 2]) < 0.9 else [1.0, 0.0, 0.0])
            norm = np.linalg.norm(cur)
        cur = cur / norm
        e[k] = cur
    return e


def torus_shape(moments, winding, hole_fraction) -> np.ndarray:
    """The flat-torus criterion per frame (:data:`TORUS_CRITERION`).

    Parameters
    ----------
    moments : ndarray, shape (n_frames, 3)
        Gyration eigenvalues in ascending order, in d^2.
    winding, hole_fraction : ndarray, shape (n_frames,)

    Returns
    -------
    ndarray of bool, shape (n_frames,)
    """
    c = TORUS_CRITERION
    g = np.asarray(moments, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        flat = g[:, 0] <= c["max_flatness"] * g[:, 1]
        round_ = g[:, 1] >= c["min_roundness"] * g[:, 2]
    return (
        flat
        & round_
        & (np.asarray(hole_fraction) <= c["max_hole_fraction"])
        & (np.abs(winding) >= c["min_winding"])
    )


def body_frame(positions, times=None, band: float = 30.0) -> BodyFrame:
    """Body-frame description of a trajectory (see the module docstring).

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions, in d; bead ``i`` bonded to ``i + 1``, the last to the first.
    times : array_like, shape (n_frames,), optional
        In tau_d (default: frame indices).
    band : float
        Hysteresis half-width of the flip count, degrees.

    Returns
    -------
    BodyFrame
    """
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[1] < 3:
        raise ValueError(f"positions: expected (n_frames, n_beads >= 3, 3), got {x.shape}")
    when = np.arange(len(x), dtype=np.float64) if times is None else np.asarray(times, float)
    centroid = x.mean(axis=1)
    rel = x - centroid[:, None, :]
    gyr = np.einsum("fni,fnj->fij", rel, rel) / x.shape[1]
    moments, vectors = np.linalg.eigh(gyr)
    normal = _follow(vectors[:, :, 0])
    e1 = _reference(normal)
    e2 = np.cross(normal, e1)
    z = np.einsum("fni,fi->fn", rel, normal)
    u = np.einsum("fni,fi->fn", rel, e1)
    v = np.einsum("fni,fi->fn", rel, e2)
    rho = np.hypot(u, v)
    phi = np.unwrap(np.arctan2(v, u), axis=0)
    area = 0.5 * np.cross(rel, np.roll(rel, -1, axis=1)).sum(axis=1)
    winding = np.einsum("fi,fi->f", area, normal) / (
        np.pi * np.maximum(moments[:, 1] + moments[:, 2], 1e-300)
    )
    radius = np.median(rho, axis=1, keepdims=True)
    hole = np.mean(rho < TORUS_CRITERION["hole_radius"] * radius, axis=1)
    tilt = np.degrees(np.arccos(np.clip(normal[:, 2], -1.0, 1.0)))
    dots = np.clip(np.einsum("fi,fi->f", normal[1:], normal[:-1]), -1.0, 1.0)
    return BodyFrame(
        times=when,
        centroid=centroid,
        normal=normal,
        moments=moments,
        rho=rho,
        phi=phi,
        z=z,
        winding=winding,
        hole_fraction=hole,
        toroidal=torus_shape(moments, winding, hole),
        tilt=tilt,
        inclination=np.minimum(tilt, 180.0 - tilt),
        flips=find_flips(tilt, when, band=band),
        max_turn_deg=float(np.degrees(np.arccos(dots.min()))) if dots.size else 0.0,
    )


def _first_run(mask: np.ndarray) -> int:
    """Length of the first stretch of True values (0 if the first value is False)."""
    off = np.flatnonzero(~mask)
    return int(off[0]) if off.size else int(mask.size)


def inclination_summary(body: BodyFrame, window: slice | None = None) -> dict:
    """Inclination, flips and torus fraction over the whole run and over a window.

    Parameters
    ----------
    body : BodyFrame
    window : slice, optional
        The steady window's frames.

    Returns
    -------
    dict
        JSON-ready: ``inclination_median_deg``, ``inclination_max_deg``,
        ``inclination_final_deg``, ``fraction_tilted`` (inclination above
        :data:`TILTED_DEG`), ``first_tilted_at`` (tau_d or None), ``window_*`` versions,
        ``tilts_after_window`` (the inclination after the window exceeds the window's
        maximum by more than 5 degrees), ``flips`` (count, times, directions),
        ``flips_per_100_tau``, ``torus_fraction``, ``torus_fraction_window``,
        ``first_torus_lifetime`` (tau_d: the first stretch of toroidal frames from t = 0; 0
        if frame 0 is not toroidal; None when every frame is toroidal: then only
        ``first_torus_lifetime_lower_bound``, the run's span, is known),
        ``first_torus_lifetime_censored``,
        ``max_turn_deg``, ``criterion``.
    """
    inc, t = body.inclination, body.times
    tilted = inc > TILTED_DEG
    sel = window if window is not None else slice(None)
    inc_w = inc[sel]
    t_w = t[sel]
    after = slice(sel.stop if sel.stop is not None else len(t), None)
    inc_after = inc[after]
    first = np.flatnonzero(tilted)
    dt = float(t[1] - t[0]) if len(t) > 1 else 0.0
    span = float(t[-1] - t[0]) + dt if len(t) else 0.0
    n_first = _first_run(body.toroidal)
    return {
        "inclination_median_deg": float(np.median(inc)),
        "inclination_max_deg": float(inc.max()),
        "inclination_final_deg": float(inc[-1]),
        "fraction_tilted": float(tilted.mean()),
        "first_tilted_at": float(t[first[0]]) if first.size else None,
        "window_inclination_median_deg": float(np.median(inc_w)),
        "window_inclination_max_deg": float(inc_w.max()),
        "tilts_after_window": bool(inc_after.size and inc_after.max() > inc_w.max() + 5.0),
        "after_window_inclination_max_deg": float(inc_after.max()) if inc_after.size else None,
        "flips": body.flips.to_dict(),
        "flips_per_100_tau": 100.0 * body.flips.count / span if span > 0 else None,
        "torus_fraction": float(body.toroidal.mean()),
        "torus_fraction_window": float(body.toroidal[sel].mean()),
        "first_torus_lifetime": n_first * dt if n_first < len(t) else None,
        "first_torus_lifetime_censored": bool(n_first >= len(t)),
        "first_torus_lifetime_lower_bound": span if n_first >= len(t) else None,
        "window": [float(t_w[0]), float(t_w[-1])],
        "max_turn_deg": body.max_turn_deg,
        "tilted_deg": TILTED_DEG,
        "criterion": dict(TORUS_CRITERION),
    }
