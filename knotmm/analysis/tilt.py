"""Tilt of the toroidal knot against gravity, and flips of the torus.

A sedimenting torus knot settles horizontal: the axis of its torus is vertical. Thermal noise
(finite Peclet number) can turn it over. The axis is the normal of the chain's mean plane,
the eigenvector of the smallest eigenvalue of the gyration tensor
``G = (1/N) sum_i (r_i - r_c)(r_i - r_c)^T`` (``r_c`` the centre of mass). Its sign is fixed
by the circulation of the chain, the area vector ``A = 1/2 sum_i (r_i - r_c) x (r_(i+1) - r_c)``
(bead order ``0, 1, ..., N-1, 0``): the oriented normal ``n`` has ``n . A >= 0``. The
circulation is carried by the chain, so when the torus turns over ``n`` turns with it.

The signed tilt is the angle between ``n`` and ``+z``, in degrees, 0..180: 0 when the beads
circulate counterclockwise seen from above (the azimuth grows along the chain, as in the
torus-knot templates), 180 when the same chain lies upside down. A flip is a crossing of 90
degrees; :func:`find_flips` counts them with a hysteresis band so that a wobble about a
steep tilt is not counted. The unsigned tilt ``min(t, 180 - t)``, 0..90, is the inclination
of the axis regardless of orientation.

The orientation is meaningful only while the chain circulates about its axis. The planar
winding ``w = (A . n) / (pi (g2 + g3))`` (``g2, g3`` the two larger eigenvalues of ``G``)
measures that: ``w = 1`` for a flat circle, ``w ~ p`` for a flat torus knot T(p, q), and
``w ~ 0`` for a collapsed coil or a chain whose loops circulate in opposite senses. Frames
with ``w`` below a threshold are left out of the flip count (:func:`tilt_analysis`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Flips",
    "TiltAnalysis",
    "find_flips",
    "planar_winding",
    "ring_normal",
    "tilt_analysis",
    "torus_tilt",
]


def _frames(positions) -> tuple[np.ndarray, bool]:
    x = np.asarray(positions, dtype=np.float64)
    single = x.ndim == 2
    if single:
        x = x[None]
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[1] < 3:
        raise ValueError(
            f"positions: expected shape (n_beads, 3) or (n_frames, n_beads, 3) with "
            f"n_beads >= 3, got {np.shape(positions)}"
        )
    return x, single


def _geometry(x):
    """Per frame: oriented normal (F, 3), gyration eigenvalues (F, 3), area vector (F, 3)."""
    c = x - x.mean(axis=1, keepdims=True)
    gyration = np.einsum("fni,fnj->fij", c, c) / c.shape[1]
    values, vectors = np.linalg.eigh(gyration)
    normal = vectors[:, :, 0]
    area = 0.5 * np.cross(c, np.roll(c, -1, axis=1)).sum(axis=1)
    sign = np.where(np.einsum("fi,fi->f", normal, area) < 0.0, -1.0, 1.0)
    return normal * sign[:, None], values, area


def ring_normal(positions) -> np.ndarray:
    """Unit normal of the chain's mean plane, oriented by the chain's circulation.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3) or (n_frames, n_beads, 3), in d
        A closed chain, bead ``N-1`` bonded to bead 0.

    Returns
    -------
    ndarray, shape (3,) or (n_frames, 3)
        Smallest-eigenvalue eigenvector of the gyration tensor, with a non-negative
        component along the area vector ``1/2 sum_i r_i x r_(i+1)`` (centred).
    """
    x, single = _frames(positions)
    normal = _geometry(x)[0]
    return normal[0] if single else normal


def planar_winding(positions):
    """How many times the chain circulates about its mean-plane normal (about p for T(p,q)).

    ``w = (A . n) / (pi (g2 + g3))`` with ``A`` the area vector, ``n`` the oriented normal
    and ``g2, g3`` the two larger eigenvalues of the gyration tensor: 1 for a flat circle,
    about p for a flat torus knot T(p, q), near 0 for a collapsed coil.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3) or (n_frames, n_beads, 3), in d

    Returns
    -------
    float or ndarray, shape (n_frames,)
    """
    x, single = _frames(positions)
    normal, values, area = _geometry(x)
    w = np.einsum("fi,fi->f", normal, area) / (
        np.pi * np.maximum(values[:, 1] + values[:, 2], 1e-300)
    )
    return float(w[0]) if single else w


def torus_tilt(positions, signed: bool = True):
    """Tilt of the torus axis against the vertical, in degrees.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3) or (n_frames, n_beads, 3), in d
    signed : bool
        True: the angle between the circulation-oriented normal (:func:`ring_normal`) and
        ``+z``, 0..180 (a flip of the torus takes it across 90). False: the inclination of
        the unoriented axis, 0..90.

    Returns
    -------
    float or ndarray, shape (n_frames,)
        Degrees.
    """
    n = ring_normal(positions)
    tilt = np.degrees(np.arccos(np.clip(n[..., 2], -1.0, 1.0)))
    if not signed:
        tilt = np.minimum(tilt, 180.0 - tilt)
    return float(tilt) if np.ndim(tilt) == 0 else tilt


@dataclass(frozen=True)
class Flips:
    """Flips of the torus found in a tilt series.

    Attributes
    ----------
    frames : ndarray of int
        Frame at which each flip completes (the tilt has crossed the far edge of the band).
    times : ndarray of float
        The same in tau_d (frame indices when no times were given).
    directions : ndarray of int
        +1 for a flip from up (tilt < 90) to down, -1 for down to up.
    fraction_down : float
        Fraction of the counted frames with a signed tilt above 90 degrees.
    notes : list of str
    """

    frames: np.ndarray
    times: np.ndarray
    directions: np.ndarray
    fraction_down: float
    notes: list[str] = field(default_factory=list)

    @property
    def count(self) -> int:
        """Number of flips."""
        return int(self.frames.size)

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "count": self.count,
            "times": [float(t) for t in self.times],
            "directions": [int(d) for d in self.directions],
            "fraction_down": float(self.fraction_down),
            "notes": list(self.notes),
        }


def find_flips(tilt, times=None, band: float = 30.0, valid=None) -> Flips:
    """Flips of the torus: crossings of 90 degrees by the signed tilt, with hysteresis.

    The torus is "up" once the tilt falls below ``90 - band`` and "down" once it rises
    above ``90 + band``; a flip is a change between the two, dated at the frame where the
    new side is reached. Excursions into the band that return are not flips, and frames
    that are not ``valid`` are skipped (they neither start nor end a flip).

    Parameters
    ----------
    tilt : array_like, shape (n_frames,)
        Signed tilt in degrees (:func:`torus_tilt` with ``signed=True``).
    times : array_like, shape (n_frames,), optional
        Frame times, in tau_d.
    band : float
        Half-width of the hysteresis band, in degrees, 0 <= band < 90.
    valid : array_like of bool, shape (n_frames,), optional
        Frames whose orientation is meaningful (default: all).

    Returns
    -------
    Flips
    """
    t = np.asarray(tilt, dtype=np.float64).reshape(-1)
    if not 0.0 <= band < 90.0:
        raise ValueError(f"band={band!r}: expected 0 <= band < 90 (degrees)")
    when = np.arange(t.size, dtype=np.float64) if times is None else np.asarray(times, float)
    if when.shape != t.shape:
        raise ValueError(f"times: expected shape {t.shape}, got {when.shape}")
    ok = np.ones(t.shape, bool) if valid is None else np.asarray(valid, bool).reshape(-1)
    if ok.shape != t.shape:
        raise ValueError(f"valid: expected shape {t.shape}, got {ok.shape}")
    state = 0
    frames, directions = [], []
    for k in np.flatnonzero(ok):
        value = t[k]
        side = -1 if value < 90.0 - band else (1 if value > 90.0 + band else 0)
        if side == 0:
            continue
        if state != 0 and side != state:
            frames.append(int(k))
            directions.append(side)
        state = side
    notes = []
    if t.size and not ok.any():
        notes.append("no frame has a meaningful orientation: no flips counted")
    elif t.size and state == 0:
        notes.append(f"the tilt never left the band 90 +- {band:g} degrees")
    frames_a = np.asarray(frames, dtype=int)
    return Flips(
        frames=frames_a,
        times=when[frames_a] if frames_a.size else np.zeros(0),
        directions=np.asarray(directions, dtype=int),
        fraction_down=float(np.mean(t[ok] > 90.0)) if ok.any() else 0.0,
        notes=notes,
    )


@dataclass(frozen=True)
class TiltAnalysis:
    """Tilt series of a trajectory and the flips found in it.

    Attributes
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    tilt : ndarray, shape (n_frames,)
        Signed tilt, degrees, 0..180.
    inclination : ndarray, shape (n_frames,)
        Unsigned tilt, degrees, 0..90.
    winding : ndarray, shape (n_frames,)
        Planar winding (:func:`planar_winding`).
    toroidal : ndarray of bool, shape (n_frames,)
        Frames with ``winding >= min_winding``: the orientation is meaningful there.
    flips : Flips
        Counted over the toroidal frames only.
    """

    times: np.ndarray
    tilt: np.ndarray
    inclination: np.ndarray
    winding: np.ndarray
    toroidal: np.ndarray
    flips: Flips

    def to_dict(self) -> dict:
        """JSON-friendly summary (no per-frame arrays)."""
        tor = self.toroidal
        return {
            "flips": self.flips.to_dict(),
            "fraction_toroidal": float(tor.mean()) if tor.size else 0.0,
            "inclination_median_deg": float(np.median(self.inclination[tor]))
            if tor.any()
            else None,
            "winding_median": float(np.median(self.winding)) if self.winding.size else None,
        }


def tilt_analysis(positions, times=None, band: float = 30.0, min_winding: float = 1.0):
    """Tilt, inclination, planar winding and flips of a trajectory.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3), in d
    times : array_like, shape (n_frames,), optional
        In tau_d (default: frame indices).
    band : float
        Hysteresis half-width of :func:`find_flips`, degrees.
    min_winding : float
        Frames with a smaller planar winding (a collapsed or unravelled chain, whose axis
        and circulation are ill-defined) are left out of the flip count. 1.0 keeps the
        frames that circulate at least once about their axis (a T(2,q) torus has ~2).

    Returns
    -------
    TiltAnalysis
    """
    x, single = _frames(positions)
    if single:
        raise ValueError("positions: expected a trajectory, shape (n_frames, n_beads, 3)")
    normal, values, area = _geometry(x)
    tilt = np.degrees(np.arccos(np.clip(normal[:, 2], -1.0, 1.0)))
    winding = np.einsum("fi,fi->f", normal, area) / (
        np.pi * np.maximum(values[:, 1] + values[:, 2], 1e-300)
    )
    when = np.arange(len(x), dtype=np.float64) if times is None else np.asarray(times, float)
    toroidal = winding >= min_winding
    return TiltAnalysis(
        times=when,
        tilt=tilt,
        inclination=np.minimum(tilt, 180.0 - tilt),
        winding=winding,
        toroidal=toroidal,
        flips=find_flips(tilt, when, band=band, valid=toroidal),
    )
