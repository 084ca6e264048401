"""Probe (issue 33): Brownian noise from an old Cholesky factor, kept exact by Lanczos.

Each Brownian step now factorises the 3N x 3N mobility (Cholesky; about a third of a step
at N = 90 on this CPU, most of it at N = 300). With the factor ``L`` of an earlier state x
(``L L^T = mu(x)``), ``B z = L S z`` with ``S = (L^-1 mu(y) L^-T)^(1/2)`` (Lanczos,
:func:`knotmm.dynamics.noise.lanczos_sqrt`) gives ``B B^T = mu(y)`` to the Lanczos tolerance
however old x is: the noise stays exact, and what the old factor changes is the cost, a few
Lanczos iterations (each two triangular solves and one product with the dense mobility) in
place of a factorisation. The matrix under the root is close to the identity, so few
iterations do; how few is what this program measures.

It runs T(2,3) of N beads at Pe = 2 with knotmm (frames every 0.002 tau_d, about one step
apart), then, for factors 1 ... 128 frames old: the median Lanczos iterations over 5 random
vectors at tolerances 1e-6 and 1e-3, and (N <= 120) the covariance error
``|B B^T - mu(y)|_F / |mu(y)|_F`` with ``B`` built column by column; and the medians of 20
timings of one ``dpotrf``, one ``dtrsv`` and one ``dsymv`` of size 3N (scipy's LAPACK and
BLAS, one thread; each repeats one call on a matrix in the cache, so they bound the cost from
below: built into the plugin, where an iteration streams both matrices from memory, the
correction was slower than the factorisation, see the README)::

    python benchmarks/probe_stale_factor.py N DURATION
    python benchmarks/probe_stale_factor.py 90 0.3

Results: ``benchmarks/README.md`` (``adaptive``). Units: d, tau_d.
"""
import sys
import tempfile
import time
from pathlib import Path

import mdtraj
import numpy as np
import scipy.linalg as sl
from scipy.linalg import blas, lapack
from threadpoolctl import threadpool_limits

from knotmm.config import RunConfig
from knotmm.dynamics.mobility import rpy_matrix
from knotmm.dynamics.noise import lanczos_sqrt
from knotmm.workflow import run

AGES = (1, 2, 4, 8, 16, 32, 64, 128)


def frames(n_beads: int, duration: float, directory: Path) -> np.ndarray:
    """Positions (frames, N, 3) in d of a Brownian run of T(2,3), Pe = 2, one frame a step."""
    cfg = RunConfig.from_dict({
        "knot": {"beads": n_beads},
        "run": {"duration": duration, "peclet": 2.0, "seed": 3, "topology_check_interval": 0.0},
        "output": {"frame_interval": 0.002},
    })
    run(cfg, directory=directory, progress=False)
    traj = mdtraj.load(str(directory / "trajectory.dcd"), top=str(directory / "topology.pdb"))
    return traj.xyz.astype(float)


def old_factor_operator(lower: np.ndarray, mobility: np.ndarray):
    """``v -> L^-1 mu L^-T v`` for Lanczos."""
    def times(v):
        u = sl.solve_triangular(lower, v, lower=True, trans="T")
        return sl.solve_triangular(lower, mobility @ u, lower=True)
    return times


def covariance_error(lower: np.ndarray, mobility: np.ndarray) -> float:
    """``|B B^T - mu|_F / |mu|_F`` for ``B = L S``, built column by column (tolerance 1e-6)."""
    times = old_factor_operator(lower, mobility)
    dim = len(mobility)
    root = np.empty((dim, dim))
    for i in range(dim):
        unit = np.zeros(dim)
        unit[i] = 1.0
        root[:, i] = lanczos_sqrt(times, unit, 1e-6)[0]
    b = lower @ root
    return float(np.linalg.norm(b @ b.T - mobility) / np.linalg.norm(mobility))


def median_time(call, repeats: int = 20) -> float:
    """Median seconds of ``call()`` over ``repeats`` calls."""
    spent = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        spent.append(time.perf_counter() - start)
    return float(np.median(spent))


def main(argv: list[str]) -> None:
    n_beads, duration = int(argv[0]), float(argv[1])
    with tempfile.TemporaryDirectory() as tmp:
        x = frames(n_beads, duration, Path(tmp) / "run")
    rng = np.random.default_rng(1)
    start = rpy_matrix(x[0])
    lower = np.linalg.cholesky(start)
    dim = len(start)
    print(f"T(2,3), N = {n_beads} (3N = {dim}), Pe = 2, {len(x)} frames 0.002 tau_d apart")
    print("factor age (frames) | Lanczos iterations, tol 1e-6 | tol 1e-3 | |BB^T - mu|/|mu|")
    for age in (a for a in AGES if a < len(x)):
        mobility = rpy_matrix(x[age])
        times = old_factor_operator(lower, mobility)
        counts = {tol: int(np.median([lanczos_sqrt(times, rng.standard_normal(dim), tol)[1]
                                      for _ in range(5)])) for tol in (1e-6, 1e-3)}
        error = f"{covariance_error(lower, mobility):.1e}" if n_beads <= 120 else "not measured"
        print(f"{age:19d} | {counts[1e-6]:29d} | {counts[1e-3]:8d} | {error}")
    with threadpool_limits(limits=1, user_api="blas"):
        matrix = np.asfortranarray(rpy_matrix(x[-1]))
        factor = np.asfortranarray(np.linalg.cholesky(matrix))
        vector = rng.standard_normal(dim)
        potrf = median_time(lambda: lapack.dpotrf(matrix, lower=1))
        trsv = median_time(lambda: blas.dtrsv(factor, vector, lower=1))
        symv = median_time(lambda: blas.dsymv(1.0, matrix, vector, lower=1))
    print(f"one thread, medians of 20: dpotrf {potrf * 1e6:.0f} us, dtrsv {trsv * 1e6:.1f} us, "
          f"dsymv {symv * 1e6:.1f} us; a Lanczos iteration (2 dtrsv + 1 dsymv) "
          f"{(2 * trsv + symv) * 1e6:.1f} us, {potrf / (2 * trsv + symv):.0f} of them cost "
          f"one dpotrf")


if __name__ == "__main__":
    main(sys.argv[1:] or ["90", "0.3"])
