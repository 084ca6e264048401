"""Brownian dynamics at finite Peclet number: thermal noise with the RPY mobility.

The overdamped chain at temperature ``kT`` obeys the Ito stochastic differential equation

.. code-block:: text

    dr = mu(r) F(r) dt + sqrt(2 kT) B(r) dW,        B B^T = mu,

with ``mu`` the 3N x 3N Rotne-Prager-Yamakawa mobility (:mod:`knotmm.dynamics.mobility`), ``F`` the
total force and ``W`` a 3N-dimensional Wiener process. In model units (``d = mu0 = F0 = 1``)
the Peclet number ``Pe = d F0 / kT`` sets ``kT = 1 / Pe`` (in F0 d); ``Pe = inf`` is the
deterministic model.

**No drift term.** The Ito equation whose stationary density is Boltzmann's,
``p ~ exp(-U/kT)``, is ``dr = [mu F + kT div(mu)] dt + sqrt(2 kT) B dW`` (the Fokker-Planck
flux ``mu F p - kT div(mu p)`` then vanishes). The RPY tensor is divergence-free:
``sum_j d/dr_j . mu_ij = 0`` for every bead ``i``, in both branches (``r >= d``: the Oseen
tensor and the source-dipole term are each divergence-free; ``r < d``:
``d/dr_k [(1 - 9r/16) delta_ik + (3/16) r_i r_k / r] = -9/16 rhat_i + 9/16 rhat_i = 0``),
and ``mu_ii = I`` is constant. So ``kT div(mu) = 0`` and the plain Ito equation above is the
right one: Euler-Maruyama needs no correction, and neither does any scheme that converges to
the Ito equation (``tests/test_brownian.py`` checks the divergence numerically). Schemes that
converge to the Stratonovich equation (noise averaged over both ends of the step) would add
the drift ``kT sum_jk (dB_ik/dr_j) B_jk``, which depends on the choice of ``B`` and is not
zero in general: they are not offered.

Noise
-----
A step needs ``B xi`` with ``xi`` standard normal (3N numbers):

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

Integrators
-----------
================== =========== ========================================================
name               weak order  update (``W = sqrt(2 kT h) B(y0) xi``, ``v = mu F``)
================== =========== ========================================================
``euler_maruyama`` 1           ``y1 = y0 + h v(y0) + W``
``ito_heun``       1 (2)       ``y* = y0 + h v(y0) + W``; ``y1 = y0 + h/2 (v(y0) + v(y*)) + W``
================== =========== ========================================================

Both draw the noise once per step, at the start of the step, so both converge to the Ito
equation above. ``ito_heun`` is weak order 2 where the mobility is constant (additive
noise) and second order in the deterministic limit; for the position-dependent RPY mobility
it is weak order 1 with a much smaller error constant on stiff modes (see
:class:`ItoHeun`). Adaptive error control does not carry over to these equations: finite
``Pe`` always runs with a fixed step.

Step size
---------
The deterministic stability limit (``h rho <= 2``, ``rho`` the largest relaxation rate) is
0.015-0.043 tau_d with the study's parameters (``rho`` about 46 / tau_d on a swirling torus,
180 / tau_d in a compact coil; see :mod:`knotmm.dynamics.deterministic`), and noise adds a random
displacement ``sqrt(2 kT h)`` per coordinate
and step (0.1 d at ``Pe = 2``, ``h = 0.01``), which pushes beads into steric contacts that
are stiffer still. Accuracy asks for less than stability: a harmonic mode of relaxation
rate ``lambda`` has stationary variance ``2 / (2 - z)`` times the exact one with
``euler_maruyama`` and ``(2 - z) / (2 - z + z^2/2)`` with ``ito_heun`` (``z = h lambda``).
For the bond modes (``lambda ~ 120``):

=========== =================== ==============
h (tau_d)   euler_maruyama      ito_heun
=========== =================== ==============
0.01        x 2.5               x 0.53
0.002       x 1.14              x 0.984
0.001       x 1.06              x 0.996
=========== =================== ==============

Use ``ito_heun`` with ``h = 0.002`` at ``Pe ~ 2`` (``euler_maruyama`` needs ``h <= 0.001``
for the same fidelity of bond fluctuations). On T(2,3), N = 90 at Pe = 2 this gave a bond
length standard deviation of 0.098 d (0.100 d at h = 0.001; ``sqrt(kT/B)`` = 0.1 d) and the
same gyration-tensor eigenvalues as h = 0.001 within their fluctuations.

Randomness
----------
Each stochastic integrator owns a ``numpy.random.Generator`` (PCG64). From a seed it is
:func:`noise_rng` ``(seed)``, a stream independent of ``default_rng(seed)`` (which the
template perturbation uses). ``get_state`` returns the bit generator state as a JSON string
(``rng_state``), which TOML, JSON and ``numpy.savez`` all store, so a resumed run continues
the identical noise sequence.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable

import numpy as np
import scipy.linalg

from knotmm.dynamics.deterministic import Integrator, make_integrator
from knotmm.dynamics.mobility import rpy_matrix, rpy_velocities
from knotmm.errors import ConfigError, SimulationFault

__all__ = [
    "BROWNIAN_INTEGRATORS",
    "CHOLESKY_MAX_BEADS",
    "NOISE_METHODS",
    "EulerMaruyama",
    "ItoHeun",
    "LanczosConvergenceError",
    "NoiseError",
    "NoiseGenerator",
    "StochasticIntegrator",
    "cholesky_noise",
    "integrator_from_config",
    "lanczos_noise",
    "lanczos_sqrt",
    "make_brownian_integrator",
    "mobility_cholesky",
    "noise_rng",
    "thermal_energy",
]

log = logging.getLogger(__name__)

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


# -- units ------------------------------------------------------------------------------------
def thermal_energy(peclet: float) -> float:
    """``kT = F0 d / Pe`` in F0 d (model units); 0 for ``Pe = inf``.

    Raises
    ------
    ConfigError
        For ``Pe <= 0`` or NaN.
    """
    peclet = float(peclet)
    if not peclet > 0:  # also NaN
        raise ConfigError(f"run.peclet = {peclet!r}: must be > 0 (inf: deterministic)")
    return 0.0 if math.isinf(peclet) else 1.0 / peclet


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
    tolerance: float = 1e-6,
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
    tolerance: float = 1e-6,
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

    def __init__(self, method: str = "auto", tolerance: float = 1e-6, max_iter: int | None = None):
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

    def describe(self) -> str:
        if self.method == "cholesky":
            return "cholesky"
        lanczos = f"lanczos (tolerance {self.tolerance:g})"
        if self.method == "lanczos":
            return lanczos
        return f"auto: cholesky up to {CHOLESKY_MAX_BEADS} beads, else {lanczos}"


# -- integrators ------------------------------------------------------------------------------
def _encode_rng_state(rng: np.random.Generator) -> str:
    return json.dumps(rng.bit_generator.state, sort_keys=True)


def _decode_rng_state(text) -> dict:
    state = json.loads(text) if isinstance(text, (str, bytes)) else dict(text)
    if not isinstance(state, dict) or "bit_generator" not in state:
        raise ValueError(f"rng_state: not a numpy bit generator state: {text!r:.80}")
    return state


class StochasticIntegrator(Integrator):
    """Base class of the fixed-step Brownian integrators (Ito, no drift correction).

    Parameters
    ----------
    timestep : float
        The fixed step ``h``, in tau_d (a step clipped by the caller's ``max_dt`` to land
        on a report time is shorter; its noise is scaled by ``sqrt`` of the actual step).
    peclet : float
        ``Pe = d F0 / kT``; ``inf`` switches the noise off (then ``euler_maruyama`` is
        :class:`knotmm.dynamics.deterministic.Euler` and ``ito_heun`` is
        :class:`knotmm.dynamics.deterministic.Heun`).
    seed : int, optional
        Seed of the noise stream (:func:`noise_rng`); ignored when ``rng`` is given.
    noise : {"auto", "cholesky", "lanczos"} or callable
        How ``B xi`` is drawn (:class:`NoiseGenerator`), or any callable
        ``(positions, rng) -> ndarray (n_beads, 3)`` with covariance ``mu``.
    lanczos_tolerance : float
        Tolerance of the Lanczos noise.
    rng : numpy.random.Generator, optional
        Use this generator (it is advanced in place) instead of one from ``seed``.

    Attributes
    ----------
    kT : float
        Thermal energy ``1 / Pe``, in F0 d.
    rng : numpy.random.Generator
        The noise stream; its state is part of :meth:`get_state`.
    """

    adaptive = False
    weak_order = 1
    evaluations_per_step = 1

    def __init__(
        self,
        timestep: float,
        peclet: float = math.inf,
        seed: int | None = None,
        noise: str | NoiseFunction = "auto",
        lanczos_tolerance: float = 1e-6,
        rng: np.random.Generator | None = None,
    ):
        super().__init__(timestep)
        self.peclet = float(peclet)
        self.kT = thermal_energy(self.peclet)
        self.seed = seed
        self.rng = noise_rng(seed) if rng is None else rng
        self.noise = NoiseGenerator(noise, lanczos_tolerance) if isinstance(noise, str) else noise

    @property
    def order(self) -> int:  # shown by describe()
        return self.weak_order

    def noise_increment(self, y: np.ndarray, h: float) -> np.ndarray:
        """``W = sqrt(2 kT h) B(y) xi``, shape (n_beads, 3), in d (zero when ``kT = 0``)."""
        if self.kT == 0.0:
            return np.zeros_like(y)
        return math.sqrt(2.0 * self.kT * h) * self.noise(y, self.rng)

    def step(self, rhs, y, max_dt=math.inf):
        """One step of ``min(timestep, max_dt)``; returns ``(y_new, dt)``."""
        h = min(self.timestep, max_dt)
        w = self.noise_increment(y, h)
        y_new = self._advance(rhs, y, h, w)
        self.n_accepted += 1
        return y_new, h

    def _advance(self, rhs, y, h, w):
        raise NotImplementedError

    def get_state(self) -> dict:
        """Step size, counters, ``peclet`` and the noise stream (``rng_state``, JSON text).

        Every value is a float, an int or a string, so the dict goes into TOML, JSON or
        ``numpy.savez`` unchanged.
        """
        state = super().get_state()
        state.update(peclet=self.peclet, rng_state=_encode_rng_state(self.rng))
        return state

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state`'s output: the next step draws the same noise."""
        super().set_state(state)
        if "rng_state" in state:
            rng_state = _decode_rng_state(state["rng_state"])
            name = rng_state["bit_generator"]
            if type(self.rng.bit_generator).__name__ != name:
                bit_generator = getattr(np.random, name, None)
                if bit_generator is None:
                    raise ValueError(f"rng_state: unknown bit generator {name!r}")
                self.rng = np.random.Generator(bit_generator())
            self.rng.bit_generator.state = rng_state
        if "peclet" in state and float(state["peclet"]) != self.peclet:
            log.warning(
                "checkpoint was written at run.peclet = %g, continuing at %g",
                float(state["peclet"]),
                self.peclet,
            )

    def describe(self) -> str:
        if self.kT == 0.0:
            return f"{self.name} (fixed dt={self.timestep:g}, Pe = inf: no noise)"
        noise = self.noise.describe() if hasattr(self.noise, "describe") else "custom"
        return (
            f"{self.name} (weak order {self.weak_order}, fixed dt={self.timestep:g}, "
            f"Pe = {self.peclet:g}, kT = {self.kT:g} F0 d, noise {noise})"
        )


class EulerMaruyama(StochasticIntegrator):
    """Euler-Maruyama for ``dr = mu F dt + sqrt(2 kT) B dW``. Weak order 1, strong order 1/2.

    .. code-block:: text

        y1 = y0 + h mu(y0) F(y0) + sqrt(2 kT h) B(y0) xi,     B B^T = mu,  xi ~ N(0, I)

    One velocity and one noise sample per step. It converges to the Ito equation, which
    is the correct one with no drift term because ``div mu = 0`` for the RPY tensor (module
    docstring). Stable for ``h rho <= 2`` (``rho`` the largest relaxation rate: h <= 0.015
    tau_d through compact coils with the study's parameters); the stationary variance of a
    harmonic mode of rate
    ``lambda`` is ``2 / (2 - h lambda)`` times the exact one, so stiff modes need
    ``h lambda << 1`` (h <= 0.001 tau_d for the bonds of the study's chain).
    """

    name = "euler_maruyama"
    weak_order = 1
    evaluations_per_step = 1

    def _advance(self, rhs, y, h, w):
        return y + h * rhs(y) + w


class ItoHeun(StochasticIntegrator):
    """Heun predictor-corrector on the drift, Ito noise drawn once at the start of the step.

    .. code-block:: text

        W  = sqrt(2 kT h) B(y0) xi,           B B^T = mu(y0),  xi ~ N(0, I)
        y* = y0 + h v(y0) + W                 (predictor: an Euler-Maruyama step)
        y1 = y0 + h/2 (v(y0) + v(y*)) + W     (trapezoidal drift, the same W)

    with ``v = mu F``. Two velocities and one noise sample per step (the noise sample,
    a Cholesky factorisation, is the larger cost at the study's sizes).

    What it converges to: the noise enters only through ``B(y0)``, so the mean increment is
    ``h v + h^2/2 (v . grad v + kT mu : grad grad v) + O(h^3)``, which is the Ito
    equation's to second order, and no spurious drift appears (unlike the Stratonovich
    "stochastic Heun" that averages ``B`` over both ends). Since ``div mu = 0`` that is the
    physical equation, whose stationary density is Boltzmann's.

    Weak order: 2 when the mobility is constant (additive noise; it is then the explicit
    order-2.0 weak scheme for additive noise of Kloeden & Platen, "Numerical Solution of
    Stochastic Differential Equations" (1992), Sec. 15.1, with Gaussian increments), and in
    the deterministic limit. With the position-dependent RPY mobility the covariance of the
    increment misses the change of ``mu`` during the step (a ``kT h^2 (v . grad + kT mu :
    grad grad) mu`` term), so it is weak order 1, with an error constant far smaller than
    Euler-Maruyama's on the stiff, nearly harmonic modes: a mode of rate ``lambda`` has
    stationary variance ``(2 - z) / (2 - z + z^2/2)`` times the exact one, ``z = h lambda``
    (0.984 at h = 0.002 tau_d for the study's bonds, against 1.14 for Euler-Maruyama).
    ``tests/test_brownian.py`` checks both orders on an Ornstein-Uhlenbeck mode;
    ``tests/test_brownian_fdt.py`` checks the Boltzmann limit on dimers with hydrodynamic
    interactions. Stability: ``h rho <= 2``, as Heun.
    """

    name = "ito_heun"
    weak_order = 1
    evaluations_per_step = 2

    def _advance(self, rhs, y, h, w):
        v0 = rhs(y)
        v1 = rhs(y + h * v0 + w)
        return y + (0.5 * h) * (v0 + v1) + w


#: Stochastic integrator name -> class.
BROWNIAN_INTEGRATORS = {cls.name: cls for cls in (EulerMaruyama, ItoHeun)}


def make_brownian_integrator(
    name: str,
    timestep: float,
    peclet: float,
    seed: int | None,
    noise: str | NoiseFunction = "auto",
    lanczos_tolerance: float = 1e-6,
) -> StochasticIntegrator:
    """Construct a stochastic integrator by name (see :data:`BROWNIAN_INTEGRATORS`).

    Parameters
    ----------
    name : {"euler_maruyama", "ito_heun"}
    timestep : float
        Fixed step, in tau_d.
    peclet : float
        ``Pe = d F0 / kT`` (``inf``: no noise).
    seed : int or None
        Seed of the noise stream (:func:`noise_rng`).
    noise : {"auto", "cholesky", "lanczos"} or callable
    lanczos_tolerance : float

    Raises
    ------
    ConfigError
        Naming ``run.integrator``, ``run.timestep``, ``run.peclet``, ``run.noise`` or
        ``run.lanczos_tolerance``.
    """
    if name not in BROWNIAN_INTEGRATORS:
        raise ConfigError(
            f"run.integrator = {name!r}: expected a Brownian integrator, one of "
            f"{', '.join(BROWNIAN_INTEGRATORS)}"
        )
    if not timestep > 0:
        raise ConfigError(f"run.timestep = {timestep!r}: must be > 0 (in tau_d)")
    return BROWNIAN_INTEGRATORS[name](
        timestep, peclet=peclet, seed=seed, noise=noise, lanczos_tolerance=lanczos_tolerance
    )


def integrator_from_config(cfg) -> Integrator:
    """The integrator a run file asks for, deterministic or Brownian.

    ``run.integrator = "auto"`` and an unset ``run.timestep`` are resolved first
    (:func:`knotmm.config.resolve_stepping`: rk23, or ito_heun with 0.002 at finite Pe).

    * ``run.integrator`` a Brownian one (``euler_maruyama``, ``ito_heun``): that
      integrator with the fixed ``run.timestep``, ``kT = 1 / run.peclet`` (no noise at
      ``Pe = inf``), ``run.seed``, ``run.noise`` and ``run.lanczos_tolerance``.
    * a deterministic one and ``run.peclet = inf``:
      :func:`knotmm.dynamics.deterministic.make_integrator` with ``run.timestep``,
      ``run.tolerance``,
      ``run.max_timestep`` and ``run.min_timestep``.
    * a deterministic one and a finite ``run.peclet``: :class:`ConfigError` (adaptive error
      control does not apply to the stochastic equation).

    Parameters
    ----------
    cfg : knotmm.config.RunConfig (or a mapping with the same dotted keys)

    Returns
    -------
    knotmm.dynamics.deterministic.Integrator
    """
    from knotmm.config import resolve_stepping

    name, timestep = resolve_stepping(cfg)
    peclet = float(cfg["run.peclet"])
    thermal_energy(peclet)  # checks the range
    if name in BROWNIAN_INTEGRATORS:
        if math.isfinite(peclet) and timestep > 0.01:
            log.warning(
                "run.timestep = %g with run.peclet = %g: above ~0.01 tau_d the stiff bond "
                "modes are unstable or strongly biased (0.002 is a good step for ito_heun)",
                timestep,
                peclet,
            )
        return make_brownian_integrator(
            name,
            timestep,
            peclet,
            cfg["run.seed"],
            noise=cfg["run.noise"],
            lanczos_tolerance=cfg["run.lanczos_tolerance"],
        )
    if math.isfinite(peclet):
        raise ConfigError(
            f"run.integrator = {name!r} cannot integrate Brownian dynamics (run.peclet = "
            f'{peclet:g}): leave run.integrator unset ("auto" picks ito_heun, step 0.002) or '
            f'use "ito_heun" / "euler_maruyama" with a fixed run.timestep such as 0.002'
        )
    try:
        return make_integrator(
            name,
            timestep,
            cfg["run.tolerance"],
            cfg["run.max_timestep"],
            cfg["run.min_timestep"],
        )
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"run.integrator = {name!r}: {exc}") from None
