"""Thermal noise with the RPY covariance: ``B xi`` with ``B B^T = mu``.

A Brownian step (:mod:`knotmm.dynamics.brownian`) needs one sample of ``B xi``, ``xi``
standard normal (3N numbers), ``mu`` the 3N x 3N Rotne-Prager-Yamakawa mobility
(:mod:`knotmm.dynamics.mobility`); see ``docs/model.md`` for the equation of motion. Two methods:

* :func:`cholesky_noise`: ``L xi`` with ``L`` the lower Cholesky factor of the dense
  :func:`knotmm.dynamics.mobility.rpy_matrix`; exact, ``O(N^3)`` per step: 0.45 ms at N = 90 and
  13 ms at N = 300 (one core).
* :func:`lanczos_noise`: the Krylov approximation of ``mu^(1/2) xi`` (symmetric square root)
  from matrix-vector products with :func:`knotmm.dynamics.mobility.rpy_velocities` only
  (Ando, Chow, Saad & Skolnick, J. Chem. Phys. 137, 064106 (2012)); ``O(k N^2)`` for ``k``
  Lanczos iterations, matrix-free, for large chains (about 30-40 iterations at tolerance
  1e-6 for torus knots of 90-300 beads: 4 ms at N = 90, 13 ms at N = 300; the two
  methods cost the same near N = 300, hence the ``"auto"`` threshold).

Both have covariance ``mu``; they give different samples for the same ``xi`` (``L`` is not
the symmetric root) but the same distribution. :class:`NoiseGenerator` selects between them
(``"auto"``: Cholesky up to :data:`CHOLESKY_MAX_BEADS` beads).

Randomness
----------
Each stochastic integrator owns a ``numpy.random.Generator`` (PCG64). From a seed it is
:func:`noise_rng` ``(seed)``, a stream independent of ``default_rng(seed)`` (which the
template perturbation uses). ``get_state`` returns the bit generator state as a JSON string
(``rng_state``, :func:`encode_rng_state`), which TOML, JSON and ``numpy.savez`` all store,
so a resumed run continues the identical noise sequence.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable

import numpy as np

from knotmm.dynamics.registry import DEFAULT_LANCZOS_TOLERANCE
from knotmm.errors import ConfigError, SimulationFault

__all__ = [
    "CHOLESKY_MAX_BEADS",
    "LANCZOS_MAX_ITER",
    "NOISE_METHODS",
    "LanczosConvergenceError",
    "NoiseError",
    "NoiseFunction",
    "NoiseGenerator",
    "cholesky_noise",
    "decode_rng_state",
    "encode_rng_state",
    "lanczos_noise",
    "lanczos_sqrt",
    "mobility_cholesky",
    "noise_rng",
]

#: ``noise = "auto"`` uses Cholesky up to this many beads, Lanczos above.
CHOLESKY_MAX_BEADS = 300

#: Accepted values of ``run.noise``.
NOISE_METHODS = ("auto", "cholesky", "lanczos")

#: Default Lanczos iteration limit (capped at 3N, where the Krylov space is complete).
LANCZOS_MAX_ITER = 200

#: Spawn key that separates the noise stream from ``default_rng(seed)``.
_NOISE_STREAM = 0x6E6F6973  # "nois"

NoiseFunction = Callable[[np.ndarray, np.random.Generator], np.ndarray]


class NoiseError(SimulationFault):
    """The thermal noise could not be generated at the current positions."""


class LanczosConvergenceError(NoiseError):
    """The Lanczos square root did not reach its tolerance within the iteration limit."""

    def __init__(self, message: str, change: float, iterations: int):
        super().__init__(message)
        self.change = change
        self.iterations = iterations


def noise_rng(seed: int | None) -> np.random.Generator:
    """The noise stream of ``seed``: PCG64 seeded by ``SeedSequence(seed, spawn_key=...)``.

    Independent of ``numpy.random.default_rng(seed)``, which the template perturbation
    uses with the same ``run.seed``. ``seed=None`` draws fresh entropy (not reproducible).
    """
    return np.random.Generator(
        np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(_NOISE_STREAM,)))
    )


# -- noise ------------------------------------------------------------------------------------
def _positions(positions) -> np.ndarray:
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"positions: expected shape (n_beads, 3), got {x.shape}")
    return x


def _standard_normal(rng: np.random.Generator, n: int, xi) -> np.ndarray:
    if xi is None:
        return rng.standard_normal(n)
    z = np.asarray(xi, dtype=np.float64).reshape(-1)
    if z.size != n:
        raise ValueError(f"xi: expected {n} numbers (3 per bead), got {z.size}")
    return z


def mobility_cholesky(positions) -> np.ndarray:
    """Lower Cholesky factor ``L`` of the RPY mobility, ``L L^T = mu``.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d

    Returns
    -------
    ndarray, shape (3 n_beads, 3 n_beads), in sqrt(mu0); bead-major rows and columns.

    Raises
    ------
    NoiseError
        If the mobility is not numerically positive definite (two beads at exactly the same
        point make it singular).
    """
    import scipy.linalg  # noqa: PLC0415 - 0.3 s, kept out of the plugin engine's runs

    from knotmm.dynamics.mobility import rpy_matrix  # numba: only the Python engine's noise

    x = _positions(positions)
    try:
        return scipy.linalg.cholesky(rpy_matrix(x), lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        raise NoiseError(
            f'run.noise = "cholesky": the RPY mobility of these {x.shape[0]} beads is not '
            f'positive definite (two beads at the same point?); use run.noise = "lanczos"'
        ) from None


def cholesky_noise(positions, rng: np.random.Generator | None = None, xi=None) -> np.ndarray:
    """One sample of ``L xi``, with ``L L^T = mu`` (Cholesky) and ``xi`` standard normal.

    Exact: the sample is Gaussian with mean 0 and covariance ``mu`` (in mu0).

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d
    rng : numpy.random.Generator
        Source of ``xi`` (3 n_beads standard normals, bead-major); unused when ``xi`` given.
    xi : array_like, shape (n_beads, 3) or (3 n_beads,), optional
        Use these standard normals instead of drawing them.

    Returns
    -------
    ndarray, shape (n_beads, 3), in sqrt(mu0)
    """
    x = _positions(positions)
    z = _standard_normal(rng, 3 * x.shape[0], xi)
    return (mobility_cholesky(x) @ z).reshape(x.shape)


def lanczos_sqrt(
    matvec: Callable[[np.ndarray], np.ndarray],
    z,
    tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
    max_iter: int | None = None,
) -> tuple[np.ndarray, int]:
    """Krylov approximation of ``A^(1/2) z`` for a symmetric positive definite ``A``.

    Lanczos with full reorthogonalisation builds an orthonormal basis ``V_k`` of the Krylov
    space ``span{z, A z, ..., A^(k-1) z}`` and the tridiagonal ``T_k = V_k^T A V_k``; the
    iterate is ``y_k = |z| V_k T_k^(1/2) e_1`` (``T_k^(1/2)`` from its eigendecomposition).
    It stops when ``|y_k - y_(k-1)| <= tolerance |y_k|``, or when the Krylov space is
    invariant (then ``y_k`` is exact up to rounding).

    Parameters
    ----------
    matvec : callable
        ``v -> A v`` on vectors of shape (n,).
    z : array_like, shape (n,)
    tolerance : float
        Relative change between successive iterates at which to stop.
    max_iter : int, optional
        Iteration limit; default :data:`LANCZOS_MAX_ITER`, capped at ``n`` (where the
        space is complete and the result exact).

    Returns
    -------
    y : ndarray, shape (n,)
    iterations : int
        Matrix-vector products used.

    Raises
    ------
    LanczosConvergenceError
        If ``max_iter < n`` iterations do not reach the tolerance.
    """
    import scipy.linalg  # noqa: PLC0415 - 0.3 s, kept out of the plugin engine's runs

    z = np.asarray(z, dtype=np.float64).reshape(-1)
    n = z.size
    if not tolerance > 0:
        raise ValueError(f"tolerance={tolerance!r}: must be > 0")
    norm_z = float(np.linalg.norm(z))
    if norm_z == 0.0:
        return np.zeros(n), 0
    m = min(n, LANCZOS_MAX_ITER if max_iter is None else int(max_iter))
    if m < 1:
        raise ValueError(f"max_iter={max_iter!r}: must be >= 1")
    basis = np.empty((m, n))
    alpha = np.empty(m)
    beta = np.empty(m)
    basis[0] = z / norm_z
    y_old = None
    change = math.inf
    for k in range(m):
        w = np.asarray(matvec(basis[k]), dtype=np.float64).reshape(-1)
        alpha[k] = basis[k] @ w
        w = w - alpha[k] * basis[k]
        if k > 0:
            w -= beta[k - 1] * basis[k - 1]
        # full reorthogonalisation, twice ("twice is enough")
        for _ in range(2):
            w -= basis[: k + 1].T @ (basis[: k + 1] @ w)
        beta[k] = float(np.linalg.norm(w))
        evals, evecs = scipy.linalg.eigh_tridiagonal(alpha[: k + 1], beta[:k])
        coeff = evecs @ (np.sqrt(np.clip(evals, 0.0, None)) * evecs[0])
        y = norm_z * (coeff @ basis[: k + 1])
        norm_y = float(np.linalg.norm(y))
        if y_old is not None:
            change = float(np.linalg.norm(y - y_old)) / max(norm_y, 1e-300)
            if change <= tolerance:
                return y, k + 1
        scale = float(np.max(np.abs(alpha[: k + 1])))
        if beta[k] <= 1e-13 * scale or k + 1 == n:
            return y, k + 1  # invariant subspace: exact
        y_old = y
        if k + 1 < m:
            basis[k + 1] = w / beta[k]
    raise LanczosConvergenceError(
        f"run.lanczos_tolerance = {tolerance:g} not reached: relative change {change:.3g} "
        f"after {m} Lanczos iterations; raise run.lanczos_tolerance or use "
        f'run.noise = "cholesky"',
        change,
        m,
    )


def lanczos_noise(
    positions,
    rng: np.random.Generator | None = None,
    tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
    max_iter: int | None = None,
    xi=None,
) -> np.ndarray:
    """One sample of ``mu^(1/2) xi`` by the Lanczos method, matrix-free.

    Uses only products ``mu v`` from :func:`knotmm.dynamics.mobility.rpy_velocities` (``O(N^2)``
    each, no 3N x 3N matrix). See :func:`lanczos_sqrt` for the iteration and its stopping
    rule; the result approaches the symmetric square root ``mu^(1/2) xi`` as the tolerance
    shrinks, so its covariance approaches ``mu``.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d
    rng : numpy.random.Generator
        Source of ``xi``; unused when ``xi`` is given.
    tolerance : float
        Relative change between successive Krylov iterates at convergence.
    max_iter : int, optional
        Iteration limit (default :data:`LANCZOS_MAX_ITER`, at most 3 n_beads).
    xi : array_like, shape (n_beads, 3) or (3 n_beads,), optional
        Use these standard normals instead of drawing them.

    Returns
    -------
    ndarray, shape (n_beads, 3), in sqrt(mu0)
    """
    x = _positions(positions)
    z = _standard_normal(rng, 3 * x.shape[0], xi)
    y, _ = _lanczos_mobility(x, z, tolerance, max_iter)
    return y.reshape(x.shape)


def _lanczos_mobility(x, z, tolerance, max_iter):
    from knotmm.dynamics.mobility import rpy_velocities  # numba: only the Python engine's noise

    shape = x.shape
    out = np.empty(shape)

    def matvec(v):
        return rpy_velocities(x, v.reshape(shape), out=out).reshape(-1).copy()

    return lanczos_sqrt(matvec, z, tolerance, max_iter)


class NoiseGenerator:
    """Callable ``(positions, rng) -> B xi``: the noise method chosen once, by name.

    Parameters
    ----------
    method : {"auto", "cholesky", "lanczos"}
        ``"auto"``: Cholesky for ``n_beads <= CHOLESKY_MAX_BEADS`` (exact, fast at these
        sizes), Lanczos above.
    tolerance : float
        Lanczos: relative change between successive iterates at convergence.
    max_iter : int, optional
        Lanczos iteration limit.

    Attributes
    ----------
    last_method : str or None
        The method used by the last call.
    last_iterations : int
        Lanczos iterations of the last call (0 for Cholesky).

    Both methods draw exactly 3 n_beads standard normals per call from ``rng``, so the
    random stream advances the same way whichever is used.
    """

    def __init__(self, method: str = "auto", tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
                 max_iter: int | None = None):
        if method not in NOISE_METHODS:
            raise ConfigError(f"run.noise = {method!r}: expected one of {', '.join(NOISE_METHODS)}")
        if not tolerance > 0:
            raise ConfigError(f"run.lanczos_tolerance = {tolerance!r}: must be > 0")
        self.method = method
        self.tolerance = float(tolerance)
        self.max_iter = max_iter
        self.last_method: str | None = None
        self.last_iterations = 0

    def method_for(self, n_beads: int) -> str:
        """The concrete method (``"cholesky"`` or ``"lanczos"``) for a chain of ``n_beads``."""
        if self.method != "auto":
            return self.method
        return "cholesky" if n_beads <= CHOLESKY_MAX_BEADS else "lanczos"

    def __call__(self, positions, rng: np.random.Generator) -> np.ndarray:
        x = _positions(positions)
        method = self.method_for(x.shape[0])
        z = rng.standard_normal(3 * x.shape[0])
        self.last_method = method
        if method == "cholesky":
            self.last_iterations = 0
            return (mobility_cholesky(x) @ z).reshape(x.shape)
        y, self.last_iterations = _lanczos_mobility(x, z, self.tolerance, self.max_iter)
        return y.reshape(x.shape)

    def matrix(self, positions):
        """``z -> B(positions) z`` for given increments ``z`` (shape (n_beads, 3)).

        Cholesky: the factor is computed once, here, and applied to every ``z``; Lanczos: each
        call runs the Krylov iteration for its ``z``. For integrators that apply the noise
        matrix of one point to several increments (a retried adaptive step).
        """
        x = _positions(positions)
        method = self.method_for(x.shape[0])
        self.last_method = method
        if method == "cholesky":
            factor = mobility_cholesky(x)
            self.last_iterations = 0
            return lambda z: (factor @ np.asarray(z, dtype=np.float64).reshape(-1)).reshape(x.shape)

        def lanczos(z):
            y, self.last_iterations = _lanczos_mobility(
                x, np.asarray(z, dtype=np.float64).reshape(-1), self.tolerance, self.max_iter)
            return y.reshape(x.shape)
        return lanczos

    def describe(self) -> str:
        if self.method == "cholesky":
            return "cholesky"
        lanczos = f"lanczos (tolerance {self.tolerance:g})"
        if self.method == "lanczos":
            return lanczos
        return f"auto: cholesky up to {CHOLESKY_MAX_BEADS} beads, else {lanczos}"



# -- random state -----------------------------------------------------------------------------
def encode_rng_state(rng: np.random.Generator) -> str:
    """The bit generator state of ``rng`` as JSON text (TOML, JSON and ``savez`` store it)."""
    return json.dumps(rng.bit_generator.state, sort_keys=True)


def decode_rng_state(text) -> dict:
    """Inverse of :func:`encode_rng_state` (also accepts the state dict itself)."""
    state = json.loads(text) if isinstance(text, (str, bytes)) else dict(text)
    if not isinstance(state, dict) or "bit_generator" not in state:
        raise ValueError(f"rng_state: not a numpy bit generator state: {text!r:.80}")
    return state
