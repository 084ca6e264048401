"""Runs of several chains and of an open chain, and a check of what a figure draws.

:func:`write_system_run` saves a trajectory of any :class:`~knotmm.model.layout.ChainLayout`
through the run's own writers (``write_pdb`` with its CONECT records, the DCD writer) and a
minimal ``run.toml``; :func:`drawn_pairs` reads every line back from a figure (Line2D and
Line3D data) and names the bead pairs its segments join, so that a test compares them with
the bonds it computes itself from the chain lengths and closed flags (:func:`allowed_pairs`),
independently of the drawing code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from knotmm.io.dcd import DCDWriter
from knotmm.io.pdb import write_pdb
from knotmm.io.rundir import TOPOLOGY_FILE, TRAJECTORY_FILE
from knotmm.model.layout import ChainLayout
from knotmm.model.topology import bead_topology

__all__ = ["allowed_pairs", "drawn_pairs", "system_positions", "write_system_run"]


def allowed_pairs(lengths, closed) -> set[tuple[int, int]]:
    """The bonded pairs of chains laid one after another: ``i - (i+1)``, a ring's closure."""
    pairs, start = set(), 0
    for n, ring in zip(lengths, closed, strict=True):
        pairs |= {(start + i, start + i + 1) for i in range(n - 1)}
        if ring:
            pairs.add((start, start + n - 1))
        start += n
    return pairs


def system_positions(n_frames: int = 24, dt: float = 0.5, lengths=(30, 20),
                     closed=(True, False), seed: int = 3) -> np.ndarray:
    """Chains side by side, each falling and turning a little: rings as wobbly circles, open
    chains as gently curved arcs; every bead off every plane of symmetry (a little noise)."""
    rng = np.random.default_rng(seed)
    times = np.arange(n_frames) * dt
    parts = []
    for c, (n, ring) in enumerate(zip(lengths, closed, strict=True)):
        k = np.arange(n)
        if ring:
            a = 2 * np.pi * k / n
            radius = 0.6 * n / (2 * np.pi)
            base = np.c_[radius * np.cos(a), radius * np.sin(a), 0.4 * np.sin(3 * a)]
        else:
            s = 0.6 * (k - (n - 1) / 2)
            base = np.c_[s, 0.02 * s**2, 0.1 * np.sin(s)]
        base = base + [12.0 * c, 0.0, 0.0] + rng.normal(scale=0.03, size=base.shape)
        frames = []
        for t in times:
            w = 0.05 * t
            rot = np.array([[np.cos(w), -np.sin(w), 0], [np.sin(w), np.cos(w), 0], [0, 0, 1]])
            frames.append(base @ rot.T - [0.0, 0.0, (1.0 + 0.2 * c) * t])
        parts.append(np.array(frames))
    return np.concatenate(parts, axis=1)


def write_system_run(directory, positions, layout: ChainLayout, frame_interval: float,
                     run_toml: str = "") -> Path:
    """``topology.pdb``, ``trajectory.dcd`` and a minimal ``run.toml`` for ``layout``."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    x = np.asarray(positions, dtype=np.float64)
    write_pdb(out / TOPOLOGY_FILE, x[0], layout=layout)
    with open(out / TRAJECTORY_FILE, "wb") as fh:
        dcd = DCDWriter(fh, bead_topology(layout), frame_interval)
        for frame in x:
            dcd.write(frame)
    (out / "run.toml").write_text(f"[output]\nframe_interval = {frame_interval!r}\n{run_toml}")
    return out


def _line_points(line) -> tuple[np.ndarray, bool]:
    """A line's points (k, 2 or 3) and whether it draws segments between them."""
    if hasattr(line, "get_data_3d"):
        pts = np.column_stack([np.asarray(v, dtype=float) for v in line.get_data_3d()])
    else:
        pts = np.column_stack([np.asarray(v, dtype=float) for v in line.get_data()])
    style = line.get_linestyle()
    return pts, style not in ("None", "none", "", " ") and line.get_visible()


def drawn_pairs(fig, beads: np.ndarray, tol: float = 1e-5) -> set[tuple[int, int]]:
    """The bead pairs joined by a drawn segment of any line of ``fig``.

    ``beads`` (n, 3): the frame's positions in the figure's frame (centred as drawn). A line
    point is matched to the bead at that place in 3D or in a projection (x-z, x-y); a line
    whose points are not beads (a reference line, a trail) must not join two beads either:
    it is skipped only when none of its points is a bead. Raises AssertionError when a
    line mixes bead and non-bead points.
    """
    projections = {3: [(0, 1, 2)], 2: [(0, 2), (0, 1)]}
    pairs: set[tuple[int, int]] = set()
    for ax in fig.axes:
        for line in ax.get_lines():
            pts, segments = _line_points(line)
            if not segments or len(pts) < 2:
                continue
            finite = np.isfinite(pts).all(axis=1)
            best = None
            for cols in projections[pts.shape[1]]:
                ref = beads[:, cols]
                dist = np.linalg.norm(pts[finite][:, None, :] - ref[None, :, :], axis=2)
                idx = np.full(len(pts), -1)
                hit = dist.min(axis=1) < tol
                idx[np.flatnonzero(finite)[hit]] = dist.argmin(axis=1)[hit]
                if best is None or (idx >= 0).sum() > (best >= 0).sum():
                    best = idx
            if not (best >= 0).any():
                continue
            assert (best[finite] >= 0).all(), f"{line}: some points are beads, some not"
            for a, b in zip(best[:-1], best[1:], strict=True):
                if a >= 0 and b >= 0 and a != b:
                    pairs.add((int(min(a, b)), int(max(a, b))))
    return pairs
