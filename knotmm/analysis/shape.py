"""Size, shape and entanglement of the chains along a run, for any knot, link or open chain.

Per frame (positions in d, all beads of equal mass, so the centre of mass is their mean):

=============================  ===============================================================
``radius_of_gyration``         ``Rg = sqrt(<|r_i - r_cm|^2>)``, in d
``radius_of_gyration_perp``    ``sqrt(<(x_i - x_cm)^2 + (y_i - y_cm)^2>)``: the part
                               perpendicular to gravity (z), in d
``asphericity``                ``((l1 - l2)^2 + (l2 - l3)^2 + (l3 - l1)^2) / (2 (l1 + l2 +
                               l3)^2)`` of the gyration tensor's eigenvalues ``l_k``
                               (dimensionless): 0 for a sphere, 1/4 for a circle, 1 for a rod
``average_crossing_number``    ACN, the Gauss double integral with ``|integrand|``
                               (:func:`knotmm.knots.writhe.average_crossing_number`, exact for
                               the polygon): crossings of a projection averaged over directions
``writhe``                     the signed Gauss integral (:func:`knotmm.knots.writhe.writhe`)
=============================  ===============================================================

Several chains (a link) are measured together: Rg and asphericity of all beads; ACN and
writhe summed over every pair of segments of the system, so pairs of segments of two
components count too (their signed sum is twice the linking number). A chain is open or
closed as its run says (:func:`chains_of`). The window means get block-bootstrap standard
errors (:func:`knotmm.analysis.bootstrap.block_bootstrap_mean`), and the series are written to
:data:`SHAPE_FILE`.
"""

from __future__ import annotations

import numpy as np

from knotmm.analysis.bootstrap import block_bootstrap_mean
from knotmm.io.rundir import SHAPE_FILE  # the run directory owns its file names
from knotmm.knots.writhe import average_crossing_number, segment_pair_gauss, writhe

__all__ = [
    "GAUSS_MAX_FRAMES",
    "OPEN_KINDS",
    "SHAPE_FILE",
    "SHAPE_SERIES",
    "ShapeSeries",
    "chains_of",
    "gauss_measures",
    "gyration_measures",
    "shape_series",
]

#: The per-frame series, in the column order of :data:`SHAPE_FILE`.
SHAPE_SERIES = (
    "radius_of_gyration",
    "radius_of_gyration_perp",
    "asphericity",
    "average_crossing_number",
    "writhe",
)
#: Most frames whose ACN and writhe are computed (O(N^2) each); evenly spaced beyond it.
GAUSS_MAX_FRAMES = 2000
#: Template kinds that are open filaments unless ``knot.closed`` says otherwise.
OPEN_KINDS = frozenset({"straight", "arc", "helix"})


def chains_of(data) -> list[tuple[slice, bool]]:
    """The chains of a loaded run: bead ranges and whether each is closed.

    Chains are the runs of consecutive beads bonded ``i - (i + 1)`` in the topology's
    bonds; a chain is closed when its last bead is bonded to its first. A single chain
    follows the run file where it speaks: ``knot.closed``, else an open ``knot.kind``
    (straight, arc, helix) is open and any other kind closed (the analysis then agrees with
    the run's knot checks, which close a ring even if the PDB lacks that bond).

    Parameters
    ----------
    data : knotmm.io.run_data.RunData

    Returns
    -------
    list of (slice, bool)
    """
    n = data.n_beads
    pairs = {tuple(sorted(map(int, b))) for b in np.asarray(data.bonds).reshape(-1, 2)}
    chains: list[tuple[slice, bool]] = []
    start = 0
    for i in range(n):
        if i == n - 1 or (i, i + 1) not in pairs:
            closed = i - start >= 2 and (start, i) in pairs
            chains.append((slice(start, i + 1), closed))
            start = i + 1
    if len(chains) == 1:
        said = data.get("knot.closed")
        kind = data.get("knot.kind")
        if said is not None:
            chains = [(slice(0, n), bool(said))]
        elif kind is not None:
            chains = [(slice(0, n), kind not in OPEN_KINDS)]
    return [(s, c and s.stop - s.start >= 3) for s, c in chains]


def gyration_measures(positions) -> dict[str, np.ndarray]:
    """Rg, its part perpendicular to z and the asphericity of every frame.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.

    Returns
    -------
    dict of ndarray, each shape (n_frames,)
        ``radius_of_gyration``, ``radius_of_gyration_perp`` (d), ``asphericity``.
    """
    x = np.asarray(positions, dtype=np.float64)
    rel = x - x.mean(axis=1, keepdims=True)
    tensor = np.einsum("fni,fnj->fij", rel, rel) / x.shape[1]
    lam = np.linalg.eigvalsh(tensor)
    trace = lam.sum(axis=1)
    spread = ((lam[:, 0] - lam[:, 1]) ** 2 + (lam[:, 1] - lam[:, 2]) ** 2
              + (lam[:, 2] - lam[:, 0]) ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        asphericity = np.where(trace > 0, spread / (2.0 * trace**2), 0.0)
    return {
        "radius_of_gyration": np.sqrt(np.mean((rel**2).sum(axis=2), axis=1)),
        "radius_of_gyration_perp": np.sqrt(np.mean(rel[..., 0] ** 2 + rel[..., 1] ** 2, axis=1)),
        "asphericity": asphericity,
    }


def _segments(x: np.ndarray, chain: slice, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points of a chain's segments, each shape (n_frames, n_segments, 3)."""
    c = x[:, chain]
    if closed:
        return c, np.roll(c, -1, axis=1)
    return c[:, :-1], c[:, 1:]


def gauss_measures(positions, chains) -> tuple[np.ndarray, np.ndarray]:
    """ACN and writhe of every frame, summed over all segment pairs of the system.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d (any length unit).
    chains : list of (slice, bool)
        From :func:`chains_of`.

    Returns
    -------
    acn, wr : ndarray, each shape (n_frames,)
    """
    x = np.asarray(positions, dtype=np.float64)
    acn = np.zeros(len(x))
    wr = np.zeros(len(x))
    for chain, closed in chains:
        if chain.stop - chain.start >= (3 if closed else 2):
            acn += average_crossing_number(x[:, chain], closed=closed)
            wr += writhe(x[:, chain], closed=closed)
    for a in range(len(chains)):
        for b in range(a + 1, len(chains)):
            p1, p2 = _segments(x, *chains[a])
            p3, p4 = _segments(x, *chains[b])
            i, j = np.meshgrid(np.arange(p1.shape[1]), np.arange(p3.shape[1]), indexing="ij")
            i, j = i.ravel(), j.ravel()
            for f in range(len(x)):  # one frame at a time bounds the memory
                g = segment_pair_gauss(p1[f, i], p2[f, i], p3[f, j], p4[f, j])
                acn[f] += 2.0 * np.abs(g).sum()
                wr[f] += 2.0 * g.sum()
    return acn, wr


class ShapeSeries:
    """The per-frame series of one window and their window means.

    Attributes
    ----------
    times : ndarray, shape (n_rows,)
        The frames measured, tau_d (every window frame, or an even subset of at most
        :data:`GAUSS_MAX_FRAMES`).
    series : dict of ndarray, each shape (n_rows,)
        :data:`SHAPE_SERIES`.
    stats : dict
        Per quantity ``value`` (window mean), ``std_error`` (block bootstrap),
        ``block_frames``, ``autocorrelation_frames`` (in rows), and ``std`` (over rows).
    stride : int
        Frames between rows.
    """

    def __init__(self, times, series: dict, stride: int):
        self.times = np.asarray(times, dtype=np.float64)
        self.series = series
        self.stride = stride
        self.stats = {}
        for name in SHAPE_SERIES:
            mean, err, block, tau = block_bootstrap_mean(series[name])
            self.stats[name] = {
                "value": mean,
                "std_error": err,
                "block_frames": block * stride,
                "autocorrelation_frames": tau * stride,
                "std": float(np.std(series[name])),
            }

    def value(self, name: str) -> float:
        """The window mean of ``name``."""
        return float(self.stats[name]["value"])

    def to_csv(self) -> str:
        """The series as CSV text: ``time`` then :data:`SHAPE_SERIES`, one row per frame."""
        rows = [",".join(("time",) + SHAPE_SERIES)]
        for k, t in enumerate(self.times):
            rows.append(",".join([f"{t:.9g}"] + [f"{self.series[n][k]:.9g}"
                                                  for n in SHAPE_SERIES]))
        return "\n".join(rows) + "\n"


def shape_series(times, positions, chains, frames: slice) -> ShapeSeries:
    """Measure :data:`SHAPE_SERIES` on the frames of a window.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.
    chains : list of (slice, bool)
        From :func:`chains_of`.
    frames : slice
        The window (``Window.frames``).

    Returns
    -------
    ShapeSeries
    """
    idx = np.arange(len(times))[frames]
    stride = max(1, -(-len(idx) // GAUSS_MAX_FRAMES))
    idx = idx[::stride]
    x = np.asarray(positions, dtype=np.float64)[idx]
    series = gyration_measures(x)
    series["average_crossing_number"], series["writhe"] = gauss_measures(x, chains)
    return ShapeSeries(np.asarray(times)[idx], series, stride)
