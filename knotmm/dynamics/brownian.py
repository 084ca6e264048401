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
the Ito equation (``tests/dynamics/test_brownian.py`` checks the divergence numerically).
Schemes that converge to the Stratonovich equation (noise averaged over both ends of the
step) would add the drift ``kT sum_jk (dB_ik/dr_j) B_jk``, which depends on the choice of
``B`` and is not zero in general: they are not offered.

Integrators
-----------
======================= =========== ===================================================
name                    weak order  update (``W = sqrt(2 kT h) B(y0) xi``, ``v = mu F``)
======================= =========== ===================================================
``euler_maruyama``      1           ``y1 = y0 + h v(y0) + W``
``ito_heun``            1 (2)       ``y* = y0 + h v(y0) + W``;
                                    ``y1 = y0 + h/2 (v(y0) + v(y*)) + W``
``leimkuhler_matthews`` 1           ``p = y0 + h v(y0) + k0``, ``k1 = sqrt(kT h/2) B(p) xi``;
                                    ``y1 = p + k1`` (``k1`` held for the next step)
======================= =========== ===================================================

The first two draw the noise once per step, at the start of the step, so both converge to
the Ito equation above; :class:`LeimkuhlerMatthews` splits each sample over two steps, with
``B`` taken at a point independent of the sample, and converges to it too. ``ito_heun`` is
weak order 2 where the mobility is constant (additive noise) and second order in the
deterministic limit; for the position-dependent RPY mobility it is weak order 1 with a much
smaller error constant on stiff modes (see :class:`ItoHeun`). ``leimkuhler_matthews`` keeps
the stationary distribution of stiff harmonic modes exact up to its stability limit (see
:class:`LeimkuhlerMatthews`). These three take a fixed step; the adaptive Brownian integrator
(an embedded Euler-Heun pair whose rejected noise is kept and split by Brownian bridges, what
``run.integrator = "auto"`` picks at finite ``Pe``) is
:class:`knotmm.dynamics.adaptive_brownian.AdaptiveItoHeun`.

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
same gyration-tensor eigenvalues as h = 0.001 within their fluctuations. Or use
``leimkuhler_matthews`` with ``h = 0.01`` (exact stationary variance of a harmonic mode at
any stable step; one velocity per step). The table is the harmonic-mode formula at
``lambda ~ 120``; measured on the same chain (``benchmarks/README.md``) the bond modes are
softer: ``ito_heun`` at 0.002 gives a bond-length variance ratio of 1.0007 +- 0.003, and at
0.01 the chain breaks (a bond past 3 d within 4 tau_d) rather than showing the 0.53 of the
table; ``leimkuhler_matthews`` at 0.01 gives 0.996-1.000.

The noise ``B xi`` and the random stream come from :mod:`knotmm.dynamics.noise`; names,
default steps and the choice of integrator for ``run.integrator = "auto"`` from
:mod:`knotmm.dynamics.registry`.
"""

from __future__ import annotations

import json
import logging
import math

import numpy as np

from knotmm.dynamics.deterministic import Integrator
from knotmm.dynamics.noise import (
    NoiseFunction,
    NoiseGenerator,
    decode_rng_state,
    encode_rng_state,
    noise_rng,
)
from knotmm.dynamics.registry import (
    DEFAULT_BROWNIAN_TIMESTEP,
    DEFAULT_LANCZOS_TOLERANCE,
    DEFAULT_LM_TIMESTEP,
)
from knotmm.units import thermal_energy

__all__ = [
    "EulerMaruyama",
    "ItoHeun",
    "LeimkuhlerMatthews",
    "StochasticIntegrator",
    "thermal_energy",
]

log = logging.getLogger(__name__)


# -- units ------------------------------------------------------------------------------------
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
        timestep: float = DEFAULT_BROWNIAN_TIMESTEP,
        peclet: float = math.inf,
        seed: int | None = None,
        noise: str | NoiseFunction = "auto",
        lanczos_tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
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
        state.update(peclet=self.peclet, rng_state=encode_rng_state(self.rng))
        return state

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state`'s output: the next step draws the same noise."""
        super().set_state(state)
        if "rng_state" in state:
            rng_state = decode_rng_state(state["rng_state"])
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
    ``tests/dynamics/test_brownian.py`` checks both orders on an Ornstein-Uhlenbeck mode;
    ``tests/dynamics/test_brownian_fdt.py`` checks the Boltzmann limit on dimers with
    hydrodynamic interactions. Stability: ``h rho <= 2``, as Heun.
    """

    name = "ito_heun"
    weak_order = 1
    evaluations_per_step = 2

    def _advance(self, rhs, y, h, w):
        v0 = rhs(y)
        v1 = rhs(y + h * v0 + w)
        return y + (0.5 * h) * (v0 + v1) + w


class LeimkuhlerMatthews(StochasticIntegrator):
    """Leimkuhler-Matthews (non-Markovian, "BAOAB limit") step: each noise sample used twice.

    .. code-block:: text

        y_{n+1} = y_n + h v(y_n) + k_n + k_{n+1}
        k_{n+1} = sqrt(kT h / 2) B(p_{n+1}) xi_{n+1},   p_{n+1} = y_n + h v(y_n) + k_n
                  B B^T = mu,  xi ~ N(0, I)

    with ``v = mu F``. The half kick ``k_{n+1}`` drawn in this step is held and used again in
    the next one, so every sample enters twice and carries ``sqrt(2 kT h) B xi`` in all: the
    noise of one Euler-Maruyama step, split over two steps. One velocity and one noise sample
    (a Cholesky factorisation) per step, half the velocities of :class:`ItoHeun`.
    Equivalently ``p_n = y_n - k_n`` is a Markov chain, ``p_{n+1} = p_n + h v(p_n + k_n) +
    2 k_n`` with ``k_n = sqrt(kT h / 2) B(p_n) xi_n``: Euler-Maruyama with the velocity taken
    half a kick ahead; the reported positions are ``y_n = p_n + k_n``.

    Invariant measure: for a harmonic potential and a constant mobility the stationary
    variance is exact for every stable step (the mode ``y' = -lambda y + sqrt(2 kT) dW``
    becomes ``y_{n+1} = (1 - z) y_n + s (xi_n + xi_{n+1})``, ``z = h lambda``,
    ``s^2 = kT h / 2``, an ARMA(1,1) process of variance ``2 s^2 / z = kT / lambda``); for
    nonlinear forces and a constant mobility it is second order (Leimkuhler & Matthews,
    Appl. Math. Res. Express 2013, 34; J. Chem. Phys. 138, 174102 (2013)). Dynamics is weak
    order 1: the mean follows Euler's drift, and the displacement over ``m`` steps has variance
    ``2 kT mu (m - 1/2) h`` (each end point holds only half a kick), so time correlations
    are right beyond a few steps, not within one.

    Position-dependent mobility: ``B`` of each sample is taken at ``p_{n+1}``, a point that
    does not depend on ``xi_{n+1}``, and both halves of the sample reuse that vector. So its
    two halves add up to one Ito increment and no spurious drift appears. Taking
    ``B(y_n) (xi_n + xi_{n+1})`` instead correlates ``y_n`` with ``xi_n`` and adds a drift of
    order ``kT sum_jk (dB_ik/dy_j) B_jk`` (a part of the Stratonovich correction), which is
    not zero for the Cholesky factor of the RPY tensor: 0.04 d/tau_d along a free pair 0.7 d
    apart at kT = 1 F0 d, measured by ``tests/dynamics/test_brownian_lm.py``. Taking
    ``B(y_n) xi_{n+1}`` (no drift either) biases the invariant measure at first order in
    ``h``; ``B(p_{n+1})`` keeps it close to second order. Bond-length variance over
    Boltzmann's of harmonic RPY dimers (``r0 = 0.6 d``, bond sd 0.1 d, symmetric-root noise,
    errors 0.0016; ``z = h k mu_rel(r0)``):

    ============ ================ ================ ================ ========
    z            B(p_{n+1})       B(y_n) xi_{n+1}  B(y_n) (both xi) ito_heun
    ============ ================ ================ ================ ========
    0.28         0.9994           1.010            1.004            0.973
    0.56         0.9994           1.021            1.010            0.867
    1.12         1.049            1.098            1.066            0.454
    ============ ================ ================ ================ ========

    On the study's chain (T(2,3), N = 90, Pe = 2, gravity 0,
    ``benchmarks/validate_brownian_equilibrium.py boltzmann``)
    the bond-length variance is 1.0003 +- 0.0012 of Boltzmann's at h = 0.01 tau_d (400
    tau_d); its centre-of-mass diffusion agrees with ``ito_heun``'s at 0.002 tau_d within the
    (4-5 %) errors there, and within 0.6 % (errors 0.9 %) on an ensemble of stiff RPY trimers
    (``benchmarks/README.md``).

    Step size: stable for ``h rho < 2`` (``rho`` the largest relaxation rate), as
    Euler-Maruyama, and for a harmonic mode the variance stays exact up to that limit (where
    ``ito_heun``'s falls to 0.53x at ``h lambda = 1.2``). The mobility of a bond changes with
    its length, so near the limit the stiffest bonds fluctuate into ``h lambda > 2`` and
    the variance grows (table above): keep ``h rho`` below about 1. On the study's chain at
    Pe = 2, h = 0.01 tau_d is the default; 0.02 blew up within 6 tau_d (``ito_heun`` did at
    0.01 within 4 tau_d).

    A step clipped by ``max_dt`` draws its half kick with its own length: the held kick keeps
    the scale of the step that drew it, so each sample still carries ``2 kT h`` of variance
    for the step it was drawn in. The first step (and the first after :meth:`reset`, when
    positions were changed from outside) draws a fresh held kick at ``y_n``. The held kick is
    part of :meth:`get_state` (``held_kick``, JSON text of the (n_beads, 3) array, exact), so
    a resumed run takes the same steps as an uninterrupted one. At ``Pe = inf`` it is
    :class:`knotmm.dynamics.deterministic.Euler`.
    """

    name = "leimkuhler_matthews"
    weak_order = 1
    evaluations_per_step = 1

    def __init__(self, timestep: float = DEFAULT_LM_TIMESTEP, *args, **kwargs):
        super().__init__(timestep, *args, **kwargs)
        self._kick: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the held half kick (the next step draws a fresh one)."""
        self._kick = None

    def step(self, rhs, y, max_dt=math.inf):
        """One step of ``min(timestep, max_dt)``; returns ``(y_new, dt)``."""
        h = min(self.timestep, max_dt)
        v = rhs(y)
        if self.kT == 0.0:
            y_new = y + h * v
        else:
            scale = math.sqrt(0.5 * self.kT * h)
            if self._kick is None or self._kick.shape != y.shape:
                self._kick = scale * self.noise(y, self.rng)
            p = y + h * v + self._kick
            self._kick = scale * self.noise(p, self.rng)
            y_new = p + self._kick
        self.n_accepted += 1
        return y_new, h

    def get_state(self) -> dict:
        """:meth:`StochasticIntegrator.get_state` plus ``held_kick`` ("" when none is held)."""
        state = super().get_state()
        state["held_kick"] = "" if self._kick is None else json.dumps(self._kick.tolist())
        return state

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state`'s output, the held half kick included."""
        super().set_state(state)  # resets: no kick held
        held = state.get("held_kick", "")
        if held:
            kick = np.asarray(json.loads(held), dtype=np.float64)
            if kick.ndim != 2 or kick.shape[1] != 3:
                raise ValueError(f"held_kick: expected shape (n_beads, 3), got {kick.shape}")
            self._kick = kick


#: Stochastic integrator name -> class.
