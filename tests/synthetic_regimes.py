"""Synthetic trajectories for the regimes of issue 13, each with a known truth (test data).

* :func:`rigid_ring`: a rigid circle that sinks, spins about its own axis and may be tilted
  or turn over; it has no swirl at all.
* :func:`tilted_torus`: the vortex knot of :mod:`synthetic`, tilted by a
  fixed angle (or by an angle that changes in time: a flipping torus, :func:`flip_angles`).
* :func:`elliptic_swirl`: the vortex knot with independent half-amplitudes in rho and z.
* :func:`noisy_swirl`: the vortex knot whose swirl phase diffuses (``d theta = 2 pi dt /
  tau_swirl + sqrt(2 D) dW``), plus Gaussian noise on every coordinate; the standard error
  of the mean swirl frequency over a window T is ``sqrt(2 D / T) / (2 pi)``.

Positions are in d, times in tau_d; gravity along -z.
"""

from __future__ import annotations

import numpy as np
from synthetic import vortex_knot_positions

__all__ = ["elliptic_swirl", "flip_angles", "noisy_swirl", "rigid_ring", "rotate_x", "tilted_torus"]


def rotate_x(positions: np.ndarray, angle_deg) -> np.ndarray:
    """Rotate positions (n_frames, n_beads, 3) about the x axis by an angle per frame (deg)."""
    a = np.radians(np.broadcast_to(np.asarray(angle_deg, dtype=np.float64), positions.shape[:1]))
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    x, y, z = positions[..., 0], positions[..., 1], positions[..., 2]
    return np.stack([x, c * y - s * z, s * y + c * z], axis=-1)


def rigid_ring(
    times,
    n_beads: int = 60,
    radius: float = 4.0,
    velocity: float = 7.0,
    tau_spin: float = 50.0,
    tilt_deg=0.0,
) -> np.ndarray:
    """A rigid circle sinking at ``velocity`` and spinning about its axis with ``tau_spin``.

    Parameters
    ----------
    times : array_like, shape (n_frames,)
    n_beads : int
    radius : float
        In d.
    velocity : float
        In d/tau_d.
    tau_spin : float
        Spin period about the ring's own axis, tau_d.
    tilt_deg : float or array_like of shape (n_frames,)
        Tilt of the ring about the x axis (an array: a ring turning over).

    Returns
    -------
    ndarray, shape (n_frames, n_beads, 3)
    """
    t = np.asarray(times, dtype=np.float64)
    a = 2.0 * np.pi * np.arange(n_beads)[None, :] / n_beads + 2.0 * np.pi * t[:, None] / tau_spin
    ring = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros_like(a)], axis=-1)
    x = rotate_x(ring, tilt_deg)
    x[..., 2] -= velocity * t[:, None]
    return x


def flip_angles(times, flip_times, duration: float = 4.0) -> np.ndarray:
    """Tilt angle (deg) that turns by 180 degrees over ``duration`` at each of ``flip_times``."""
    t = np.asarray(times, dtype=np.float64)
    angle = np.zeros_like(t)
    for t0 in flip_times:
        angle += 180.0 * np.clip((t - t0) / duration, 0.0, 1.0)
    return angle


def tilted_torus(times, tilt_deg=0.0, velocity: float = 7.0, **vortex) -> np.ndarray:
    """The vortex knot tilted about the x axis through its centre, sinking at ``velocity``.

    Parameters
    ----------
    times : array_like, shape (n_frames,)
    tilt_deg : float or array_like of shape (n_frames,)
        Fixed tilt, or one per frame (:func:`flip_angles` for a flipping torus).
    velocity : float
        In d/tau_d.
    **vortex
        Passed to :func:`synthetic.vortex_knot_positions` (not ``z_com``).

    Returns
    -------
    ndarray, shape (n_frames, n_beads, 3)
    """
    t = np.asarray(times, dtype=np.float64)
    x = vortex_knot_positions(t, z_com=np.zeros_like(t), velocity=0.0, **vortex)
    x = rotate_x(x, tilt_deg)
    x[..., 2] -= velocity * t[:, None]
    return x


def elliptic_swirl(
    times, amplitude_rho: float, amplitude_z: float, p: int = 2, q: int = 3, **vortex
) -> np.ndarray:
    """The vortex knot with half-amplitude ``amplitude_rho`` in rho and ``amplitude_z`` in z.

    Built from :func:`~synthetic.vortex_knot_positions` with ``C =
    amplitude_rho`` (which sets rho and alpha) by rescaling the z oscillation from ``C k``,
    ``k = sqrt(p^2 + q^2) / q``, to ``amplitude_z``.
    """
    t = np.asarray(times, dtype=np.float64)
    velocity = vortex.pop("velocity", 7.0)
    x = vortex_knot_positions(
        t, p=p, q=q, swirl_amplitude=amplitude_rho, z_com=np.zeros_like(t), **vortex
    )
    k = np.hypot(p, q) / q
    x[..., 2] *= amplitude_z / (amplitude_rho * k)
    x[..., 2] -= velocity * t[:, None]
    return x


def noisy_swirl(
    times,
    diffusion: float,
    noise: float = 0.0,
    n_beads: int = 60,
    p: int = 2,
    q: int = 3,
    rho0: float = 3.0,
    swirl_amplitude: float = 0.4,
    tau_swirl: float = 10.0,
    velocity: float = 7.0,
    seed: int = 0,
) -> np.ndarray:
    """The vortex knot (no rotation) with a diffusing swirl phase and coordinate noise.

    Parameters
    ----------
    times : array_like, shape (n_frames,)
        Uniform, in tau_d.
    diffusion : float
        Phase diffusion coefficient D, rad^2 / tau_d.
    noise : float
        Standard deviation of Gaussian noise on every coordinate, d.
    n_beads, p, q, rho0, swirl_amplitude, tau_swirl, velocity
        As in :func:`~synthetic.vortex_knot_positions`.
    seed : int

    Returns
    -------
    ndarray, shape (n_frames, n_beads, 3)
    """
    t = np.asarray(times, dtype=np.float64)
    rng = np.random.default_rng(seed)
    dt = float(t[1] - t[0])
    steps = rng.normal(scale=np.sqrt(2.0 * diffusion * dt), size=t.size - 1)
    theta0 = 2.0 * np.pi * t / tau_swirl + np.r_[0.0, np.cumsum(steps)]
    a = 2.0 * np.pi * p * np.arange(n_beads)[None, :] / n_beads
    theta = theta0[:, None] + q * a / p
    c = swirl_amplitude
    rho = rho0 + c * np.sin(theta)
    alpha = a + c * p / (q * rho0) * np.cos(theta)
    z = -velocity * t[:, None] + c * np.hypot(p, q) / q * np.cos(theta)
    x = np.stack([rho * np.cos(alpha), rho * np.sin(alpha), z], axis=-1)
    if noise > 0:
        x = x + rng.normal(scale=noise, size=x.shape)
    return x
