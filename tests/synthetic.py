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
saves any trajectory as a run directory through the writers ``knotmm run`` uses (the DCD
writer, ``write_pdb``, ``write_run_toml``, the observables reporter), for tests and for
checking the analysis on data where the truth is known.

Test data, not part of the package: ``tests/conftest.py`` puts this folder on ``sys.path``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from knotmm.config import RunConfig
from knotmm.engine.reporters import ObservablesReporter
from knotmm.io.dcd import DCDWriter
from knotmm.io.observables import ENERGY_TERMS
from knotmm.io.pdb import write_pdb
from knotmm.io.rundir import OBSERVABLES_FILE, TOPOLOGY_FILE, TRAJECTORY_FILE, write_run_toml
from knotmm.model.layout import ChainLayout
from knotmm.model.topology import bead_topology

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
    phase: float = 0.0,
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
    phase : float
        Added to every bead's swirl angle, in rad: with ``p = 1`` and ``phase = pi`` the
        second component of the torus link T(2, 2q).

    Returns
    -------
    ndarray, shape (n_frames, n_beads, 3)
        Positions in d.
    """
    t = np.asarray(times, dtype=np.float64)[:, None]
    r0 = np.broadcast_to(np.asarray(rho0, dtype=np.float64), t.shape[:1])[:, None]
    amp = np.broadcast_to(np.asarray(swirl_amplitude, dtype=np.float64), t.shape[:1])[:, None]
    a = 2.0 * np.pi * p * np.arange(n_beads)[None, :] / n_beads
    theta = 2.0 * np.pi * t / tau_swirl + q * a / p + phase
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


class _Frame:
    """What the run's reporters read of a Simulation, for one frame of a given trajectory.

    Energies are unknown for a made-up trajectory: NaN in ``observables.csv``.
    """

    def __init__(self, layout: ChainLayout, frame_interval: float):
        self._bonds = layout.bonds()
        self.timestep = frame_interval
        self.n_evaluations = 0
        self.positions = self.time = self.currentStep = None

    def at(self, k: int, positions: np.ndarray, time: float) -> _Frame:
        self.positions, self.time, self.currentStep = positions, time, k
        return self

    def energies(self) -> dict[str, float]:
        return dict.fromkeys(ENERGY_TERMS, math.nan)

    def bond_lengths(self) -> np.ndarray:
        i, j = self._bonds[:, 0], self._bonds[:, 1]
        return np.linalg.norm(self.positions[j] - self.positions[i], axis=1)


def write_run_directory(
    directory,
    positions,
    frame_interval: float,
    config: dict | None = None,
    write_run_file: bool = True,
    layout: ChainLayout | None = None,
) -> Path:
    """Save positions as a run directory, through the writers of ``knotmm run``.

    ``trajectory.dcd`` by :class:`knotmm.io.dcd.DCDWriter` (the run's
    :class:`~knotmm.engine.reporters.DCDReporter` writes through it), ``topology.pdb`` by
    :func:`knotmm.io.pdb.write_pdb`, ``run.toml`` by :func:`knotmm.io.rundir.write_run_toml`
    (the resolved run file, validated), ``observables.csv`` by the run's
    :class:`~knotmm.engine.reporters.ObservablesReporter` (energies NaN: not known here).

    Parameters
    ----------
    directory : str or Path
        Created if missing.
    positions : array_like, shape (n_frames, n_beads, 3)
        Bead positions of the chains (``layout``), in d (written in Angstrom, 1 d = 10 A).
    frame_interval : float
        Time between frames, in tau_d.
    config : dict, optional
        Run-file tables to write (merged over ``[knot] beads``, ``[run] duration`` and
        ``[output] frame_interval``, which are filled in from the data); its ``[knotmm]``
        table is the facts table of ``run.toml`` (``version = "synthetic"`` unless given).
    write_run_file : bool
        False leaves out ``run.toml`` (a bare DCD/PDB pair).
    layout : ChainLayout, optional
        The chains (default one ring of all beads); any other is recorded in run.toml's
        ``[knotmm.layout]``, as a run records it.

    Returns
    -------
    Path
        The directory.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    x = np.asarray(positions, dtype=np.float64)
    n_frames, n_beads = x.shape[:2]
    interval = float(frame_interval)
    layout = ChainLayout((n_beads,), (True,)) if layout is None else layout

    write_pdb(out / TOPOLOGY_FILE, x[0], layout=layout)
    with open(out / TRAJECTORY_FILE, "wb") as fh:
        dcd = DCDWriter(fh, bead_topology(layout), interval)
        for frame in x:
            dcd.write(frame)

    if write_run_file:
        tables: dict = {
            "knot": {"beads": n_beads},
            "run": {"duration": (n_frames - 1) * interval},
            "output": {"directory": str(out), "frame_interval": interval},
        }
        for name, values in (config or {}).items():
            tables.setdefault(name, {}).update(values)
        facts = tables.pop("knotmm", {})
        facts.setdefault("version", "synthetic")
        if not layout.is_single_ring:
            facts.setdefault("layout", layout.to_record())
        write_run_toml(out, RunConfig.from_dict(tables), facts)

    rows = ObservablesReporter(out / OBSERVABLES_FILE, interval)
    frame = _Frame(layout, interval)
    try:
        for k, xk in enumerate(x):
            rows.report(frame.at(k, xk, k * interval), None)
    finally:
        rows.close()
    return out
