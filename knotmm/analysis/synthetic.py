"""Synthetic trajectories with known answers, built from the vortex-knot formula.

A torus knot T(p, q) that falls at speed V, swirls with period tau_swirl and rotates
rigidly with period tau_rot (docs/model.md, "Observables"). Bead ``i`` sits at template angle
``a_i = 2 pi p i / N`` and carries the swirl phase ``q a_i / p`` (the loops wind q times
around the torus core), so every frame is a torus knot with an elliptic cross-section:

    rho_i(t)   = rho0 + C sin(theta_i)
    alpha_i(t) = a_i + C p / (q rho0) cos(theta_i) + 2 pi t / tau_rot
    z_i(t)     = z_start - V t + C sqrt(p^2 + q^2) / q cos(theta_i)
    theta_i(t) = 2 pi t / tau_swirl + q a_i / p

The unmirrored knot is right-handed (positive writhe); ``mirror=True`` reflects x -> -x,
which gives the left-handed knot rotating the other way. :func:`write_run_directory`
saves any trajectory as a run directory like ``knotmm run`` writes, for tests and for
checking the analysis on data where the truth is known.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from knotmm.io.rundir import OBSERVABLES_FILE, RUN_FILE, TOPOLOGY_FILE, TRAJECTORY_FILE
from knotmm.units import d_to_angstrom

__all__ = ["vortex_knot_positions", "write_run_directory"]


def vortex_knot_positions(
    times,
    n_beads: int = 90,
    p: int = 2,
    q: int = 3,
    rho0=4.3,
    swirl_amplitude=0.5,
    tau_swirl: float = 20.0,
    tau_rot: float = 400.0,
    velocity: float = 7.0,
    mirror: bool = False,
    noise: float = 0.0,
    seed: int = 0,
    z_com=None,
) -> np.ndarray:
    """Bead positions of a rotating, swirling, falling torus knot.

    Parameters
    ----------
    times : array_like, shape (n_frames,)
        Frame times, in tau_d.
    n_beads, p, q : int
        Number of beads N and the torus knot T(p, q).
    rho0, swirl_amplitude : float or array_like of shape (n_frames,)
        Major radius rho0 and swirl amplitude C, in d (an array makes them time-dependent).
    tau_swirl, tau_rot : float
        Swirl and rotation periods, in tau_d; a negative ``tau_rot`` rotates clockwise seen
        from above.
    velocity : float
        Sedimentation speed V, in d/tau_d (the knot falls towards -z).
    mirror : bool
        Reflect x -> -x: the mirror image (left-handed for T(2, 3)), rotating the other way.
    noise : float
        Standard deviation of independent Gaussian noise on every coordinate, in d.
    seed : int
        Seed of the noise.
    z_com : array_like of shape (n_frames,), optional
        Height of the centre of the structure, in d; default ``-velocity * t``.

    Returns
    -------
    ndarray, shape (n_frames, n_beads, 3)
        Positions in d.
    """
    t = np.asarray(times, dtype=np.float64)[:, None]
    r0 = np.broadcast_to(np.asarray(rho0, dtype=np.float64), t.shape[:1])[:, None]
    amp = np.broadcast_to(np.asarray(swirl_amplitude, dtype=np.float64), t.shape[:1])[:, None]
    a = 2.0 * np.pi * p * np.arange(n_beads)[None, :] / n_beads
    theta = 2.0 * np.pi * t / tau_swirl + q * a / p
    rho = r0 + amp * np.sin(theta)
    alpha = a + amp * p / (q * r0) * np.cos(theta) + 2.0 * np.pi * t / tau_rot
    height = -velocity * t if z_com is None else np.asarray(z_com, dtype=np.float64)[:, None]
    z = height + amp * np.sqrt(p * p + q * q) / q * np.cos(theta)
    x = np.stack([rho * np.cos(alpha), rho * np.sin(alpha), z], axis=-1)
    if mirror:
        x[..., 0] *= -1.0
    if noise > 0:
        x = x + np.random.default_rng(seed).normal(scale=noise, size=x.shape)
    return x


def write_run_directory(
    directory,
    positions,
    frame_interval: float,
    config: dict | None = None,
    write_run_file: bool = True,
) -> Path:
    """Save positions as a run directory: trajectory.dcd, topology.pdb, run.toml.

    Parameters
    ----------
    directory : str or Path
        Created if missing.
    positions : array_like, shape (n_frames, n_beads, 3)
        Bead positions, in d (written in Angstrom, 1 d = 10 A).
    frame_interval : float
        Time between frames, in tau_d.
    config : dict, optional
        Run-file tables to write (merged over ``[knot] beads``, ``[run] duration`` and
        ``[output] frame_interval``, which are filled in from the data).
    write_run_file : bool
        False leaves out ``run.toml`` (a bare DCD/PDB pair).

    Returns
    -------
    Path
        The directory.
    """
    import mdtraj
    import tomli_w
    from mdtraj.formats import DCDTrajectoryFile

    from knotmm.io.pdb import mdtraj_topology

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    x = np.asarray(positions, dtype=np.float64)
    n_frames, n_beads = x.shape[:2]

    top = mdtraj_topology(n_beads)
    # mdtraj stores nm; 1 d = 1 nm, so d values go in unchanged and come out as 10 A per d.
    mdtraj.Trajectory(x[:1], top).save_pdb(str(out / TOPOLOGY_FILE))
    with DCDTrajectoryFile(str(out / TRAJECTORY_FILE), "w") as fh:
        fh.write(d_to_angstrom(x).astype(np.float32))

    if write_run_file:
        tables: dict = {
            "knot": {"beads": n_beads},
            "run": {"duration": (n_frames - 1) * float(frame_interval)},
            "output": {"directory": str(out), "frame_interval": float(frame_interval)},
        }
        for name, values in (config or {}).items():
            tables.setdefault(name, {}).update(values)
        tables.setdefault("knotmm", {}).setdefault("version", "synthetic")
        (out / RUN_FILE).write_text(tomli_w.dumps(tables))

    com = x.mean(axis=1)
    times = np.arange(n_frames) * float(frame_interval)
    rows = ["time,step,com_x,com_y,com_z"]
    rows += [
        f"{t:.6g},{k},{c[0]:.6g},{c[1]:.6g},{c[2]:.6g}"
        for k, (t, c) in enumerate(zip(times, com, strict=True))
    ]
    (out / OBSERVABLES_FILE).write_text("\n".join(rows) + "\n")
    return out
