"""Cylindrical coordinates about the vertical axis through the centre of mass.

All beads have the same mass, so the centre of mass is the mean bead position. The
observables of the study are measured in cylindrical coordinates (rho, alpha, z) about the
vertical line through it: rho is the distance from that line, alpha the azimuth (counted
counterclockwise seen from above, i.e. from +z looking down along gravity) and z the height
above the centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Cylindrical", "cylindrical", "winding_numbers"]


@dataclass(frozen=True)
class Cylindrical:
    """Bead coordinates in the centre-of-mass frame.

    Attributes
    ----------
    com : ndarray, shape (n_frames, 3)
        Centre of mass, in d.
    rho : ndarray, shape (n_frames, n_beads)
        Distance from the vertical axis through the centre of mass, in d.
    alpha : ndarray, shape (n_frames, n_beads)
        Azimuth, in rad, unwrapped along time for each bead (continuous, may exceed 2 pi).
    z : ndarray, shape (n_frames, n_beads)
        Height above the centre of mass, in d.
    """

    com: np.ndarray
    rho: np.ndarray
    alpha: np.ndarray
    z: np.ndarray


def cylindrical(positions: np.ndarray) -> Cylindrical:
    """Cylindrical coordinates of every bead about the vertical axis through the COM.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions, in d.

    Returns
    -------
    Cylindrical
        ``alpha`` is unwrapped along time per bead, so a steady rotation is a straight line.
    """
    x = np.asarray(positions, dtype=np.float64)
    com = x.mean(axis=1)
    rel = x - com[:, None, :]
    rho = np.hypot(rel[..., 0], rel[..., 1])
    alpha = np.unwrap(np.arctan2(rel[..., 1], rel[..., 0]), axis=0)
    return Cylindrical(com=com, rho=rho, alpha=alpha, z=rel[..., 2])


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def winding_numbers(positions: np.ndarray, rings=None) -> tuple[np.ndarray, np.ndarray]:
    """How often the closed chain winds around the vertical axis and around its core.

    For a torus knot T(p, q) lying on a horizontal torus, the chain goes ``p`` times around
    the vertical axis through the centre of mass (the azimuth alpha advances by 2 pi p
    along the chain) and ``q`` times around the torus core (the angle of the bead in the
    torus cross-section, measured from the mean radius and the centre-of-mass height,
    advances by 2 pi q). Signs follow bead order and handedness.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions, in d; bead ``i`` is bonded to ``i + 1`` and the last to the first.
    rings : sequence of slice, optional
        The closed chains of a link: the windings of each about the whole system's axis and
        core, summed (a torus link T(p, q) gives p and q). Default: one ring of all beads.

    Returns
    -------
    axis_winding, core_winding : ndarray, shape (n_frames,)
        Signed winding numbers (floats; integers for a clean torus-like shape).
    """
    cyl = cylindrical(positions)
    rel = np.asarray(positions, dtype=np.float64) - cyl.com[:, None, :]
    alpha = np.arctan2(rel[..., 1], rel[..., 0])
    psi = np.arctan2(cyl.rho - cyl.rho.mean(axis=1, keepdims=True), cyl.z)
    rings = [slice(0, alpha.shape[1])] if rings is None else list(rings)
    turns = np.zeros((2, alpha.shape[0]))
    for ring in rings:
        for k, angle in enumerate((alpha[:, ring], psi[:, ring])):
            turns[k] += _wrap(np.roll(angle, -1, axis=1) - angle).sum(axis=1)
    return turns[0] / (2.0 * np.pi), turns[1] / (2.0 * np.pi)
