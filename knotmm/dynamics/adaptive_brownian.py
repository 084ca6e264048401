"""An adaptive Brownian integrator: the Euler-Heun pair with rejection sampling with memory.

.. code-block:: text

    dW ~ N(0, h I)                          the Wiener increment over the step (3N numbers)
    W  = sqrt(2 kT) B(y0) dW,               B B^T = mu(y0)
    yE = y0 + h v(y0) + W                   Euler-Maruyama
    y1 = y0 + h/2 (v(y0) + v(yE)) + W       Ito-Heun (the step taken)
    err = y1 - yE = h/2 (v(yE) - v(y0))     the local error estimate

with ``v = mu F``. The pair is that of Sammüller and Schmidt, J. Chem. Phys. 155, 134107
(2021): both members share the noise, so their difference measures how much the drift
changes over the step, noise displacement included. That is what breaks fixed steps in this
model: at ``kT >~ 1 F0 d`` a noise kick pushes two beads into the soft steric core (about
0.35 d apart), where the force is of order 10^3 F0 and one explicit step of 0.01 tau_d throws
a bead 10 d. The error estimate sees ``v(yE)`` jump and the step is retried shorter.

**One Wiener path whatever the steps** (rejection sampling with memory, Rackauckas and Nie,
Discrete Contin. Dyn. Syst. B 22 (2017) 2731). A rejected step keeps the increment ``dW``
it drew over ``h``. The retry over ``h' < h`` takes the Brownian bridge's value at ``h'``,
``dW' = (h'/h) dW + sqrt(h' (h - h') / h) xi``, and the rest of the increment, ``dW - dW'``
over ``h - h'``, waits in a queue of future increments that later steps consume (splitting
them by the same bridge, or adding fresh increments beyond them). So the noise a run sees is
one Brownian path sampled at the accepted times, not a path biased towards the increments
that were accepted: on a stiff anharmonic dimer at tolerance 0.01 d, drawing fresh noise
after each rejection halves the bond-length variance, while the queue keeps it within 0.2 %
of Boltzmann's (``tests/dynamics/test_adaptive_brownian.py``). The path is one path given
the steps a run takes; a run at another tolerance takes other steps and draws its bridges in
another order, so it samples another path. ``B`` is taken at the step's start (the Ito
equation, which needs no drift correction since ``div mu = 0``;
:mod:`knotmm.dynamics.brownian`), from the noise method of
:class:`knotmm.dynamics.noise.NoiseGenerator` (Cholesky; Lanczos above 300 beads).

**Step control.** The error is the largest per-bead displacement of ``err`` over
``tolerance`` (d). It scales as ``h^(3/2)`` where the noise dominates (``v(yE) - v(y0)`` is
the Jacobian times a ``sqrt(h)`` kick), so the proportional-integral controller uses that
order: an accepted step grows by ``0.9 e^(-0.7/q) e_old^(0.4/q)`` (``q = 3/2``, within 0.2-5),
a rejected one shrinks by ``max(0.1, 0.9 e^(-1/q))``; steps stay within ``min_timestep`` and
``max_timestep``. A retry at the same start reuses ``v(y0)`` and the factor of ``B(y0)``.
At ``Pe = inf`` it is an adaptive Heun method (second order, embedded Euler).
"""

from __future__ import annotations

import json
import math

import numpy as np

from knotmm.dynamics.brownian import StochasticIntegrator
from knotmm.dynamics.deterministic import StepSizeUnderflow, _error_norm
from knotmm.dynamics.noise import NoiseFunction, NoiseGenerator
from knotmm.dynamics.registry import (
    DEFAULT_BROWNIAN_TIMESTEP,
    DEFAULT_BROWNIAN_TOLERANCE,
    DEFAULT_LANCZOS_TOLERANCE,
    DEFAULT_MAX_TIMESTEP,
    DEFAULT_MIN_TIMESTEP,
)

__all__ = ["AdaptiveItoHeun", "WienerQueue"]

#: The error estimate's order in the step, for the controller's exponents.
ERROR_ORDER = 1.5
#: The default tolerance, in d: the registry's
#: (:data:`knotmm.dynamics.registry.DEFAULT_BROWNIAN_TOLERANCE`, where its reason is told).
DEFAULT_TOLERANCE = DEFAULT_BROWNIAN_TOLERANCE


class WienerQueue:
    """Increments of one Wiener process over future intervals, earliest first.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of fresh increments and of the bridges' normals.
    shape : tuple
        Shape of one increment (``(n_beads, 3)``).
    """

    def __init__(self, rng: np.random.Generator, shape: tuple):
        self.rng = rng
        self.shape = tuple(shape)
        self.pending: list[tuple[float, np.ndarray]] = []

    def take(self, h: float) -> np.ndarray:
        """The increment over the next ``h`` (tau_d), shape ``shape``; removes it from the queue.

        Whole queued intervals are added while they fit; one that is longer than what is left
        is split by the Brownian bridge; beyond the queue fresh increments are drawn.
        """
        total = np.zeros(self.shape)
        need = float(h)
        while need > 0.0:
            if not self.pending:
                total += math.sqrt(need) * self.rng.standard_normal(self.shape)
                break
            span, dw = self.pending[0]
            if span <= need * (1.0 + 1e-12):  # the whole interval (to rounding) fits
                self.pending.pop(0)
                total += dw
                need = 0.0 if span >= need * (1.0 - 1e-12) else need - span
                continue
            # bridge: the value at `need` of a path that reaches dw at `span`
            first = (need / span) * dw + math.sqrt(need * (span - need) / span) * (
                self.rng.standard_normal(self.shape))
            self.pending[0] = (span - need, dw - first)
            total += first
            break
        return total

    def give_back(self, h: float, dw: np.ndarray) -> None:
        """Put the increment ``dw`` over the next ``h`` back at the front (a rejected step)."""
        self.pending.insert(0, (float(h), np.array(dw, dtype=np.float64)))

    def to_json(self) -> str:
        return json.dumps([[span, dw.reshape(-1).tolist()] for span, dw in self.pending])

    def load_json(self, text: str) -> None:
        self.pending = [(float(span), np.asarray(dw, dtype=np.float64).reshape(self.shape))
                        for span, dw in (json.loads(text) if text else [])]


class AdaptiveItoHeun(StochasticIntegrator):
    """Adaptive Brownian dynamics: the Euler-Heun pair, PI control, rejection with memory.

    See the module docstring for the update, the error estimate and the noise path. Two
    velocities and one noise factorisation per attempt (a retry reuses the start's velocity
    and factor). Weak order 1 (the step taken is :class:`knotmm.dynamics.brownian.ItoHeun`'s).

    Parameters
    ----------
    timestep : float
        The first step to try, in tau_d.
    peclet, seed, noise, lanczos_tolerance, rng
        As :class:`knotmm.dynamics.brownian.StochasticIntegrator`.
    tolerance : float
        Largest per-bead error ``|h/2 (v(yE) - v(y0))|`` per step, in d.
    max_timestep, min_timestep : float
        Step bounds, in tau_d; a step below ``min_timestep`` raises
        :class:`knotmm.dynamics.deterministic.StepSizeUnderflow`.
    """

    name = "ito_heun_adaptive"
    adaptive = True
    weak_order = 1
    evaluations_per_step = 2

    def __init__(self, timestep: float = DEFAULT_BROWNIAN_TIMESTEP, peclet: float = math.inf,
                 seed: int | None = None, noise: str | NoiseFunction = "auto",
                 lanczos_tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
                 rng: np.random.Generator | None = None, tolerance: float = DEFAULT_TOLERANCE,
                 max_timestep: float = DEFAULT_MAX_TIMESTEP,
                 min_timestep: float = DEFAULT_MIN_TIMESTEP):
        super().__init__(timestep, peclet, seed, noise, lanczos_tolerance, rng)
        if not tolerance > 0:
            raise ValueError(f"tolerance={tolerance!r}: must be > 0")
        self.tolerance = float(tolerance)
        self.max_timestep = float(max_timestep)
        self.min_timestep = float(min_timestep)
        self.timestep = min(self.timestep, self.max_timestep)
        self._err_old = 1.0
        self._queue: WienerQueue | None = None

    def _wiener(self, shape) -> WienerQueue:
        if self._queue is None or self._queue.shape != tuple(shape):
            self._queue = WienerQueue(self.rng, shape)
        self._queue.rng = self.rng
        return self._queue

    def _noise_matrix(self, y):
        """``z -> B(y) z`` for the step's start (one factorisation for every retry)."""
        if isinstance(self.noise, NoiseGenerator):
            return self.noise.matrix(y)
        fixed = self.noise

        def apply(z):  # a custom noise function takes its own normals: feed it these
            return fixed(y, _Replay(z))
        return apply

    def step(self, rhs, y, max_dt=math.inf):
        """One accepted step of at most ``max_dt``; returns ``(y_new, dt)``."""
        queue = self._wiener(y.shape)
        v0 = rhs(y)
        apply_b = None
        noisy = self.kT > 0.0
        while True:
            h = min(self.timestep, max_dt)
            if noisy:
                dw = queue.take(h)
                if apply_b is None:
                    apply_b = self._noise_matrix(y)
                w = math.sqrt(2.0 * self.kT) * apply_b(dw)
            else:
                w = 0.0
            y_euler = y + h * v0 + w
            v1 = rhs(y_euler)
            y1 = y + (0.5 * h) * (v0 + v1) + w
            err = _error_norm((0.5 * h) * (v1 - v0), self.tolerance)
            if err <= 1.0:
                fac = self._pi_factor(err)
                if h >= self.timestep or fac < 1.0:  # a step clipped by max_dt keeps its size
                    self.timestep = min(self.max_timestep, h * fac)
                self._err_old = max(err, 1e-4)
                self.n_accepted += 1
                return y1, h
            self.n_rejected += 1
            if noisy:
                queue.give_back(h, dw)
            fac = 0.1 if not math.isfinite(err) else max(0.1, 0.9 * err ** (-1.0 / ERROR_ORDER))
            self.timestep = h * fac
            if self.timestep < self.min_timestep:
                raise StepSizeUnderflow(
                    self.timestep, f"{self.name} error estimate {err:.3g} x tolerance")

    def _pi_factor(self, err: float) -> float:
        if err == 0.0:
            return 5.0
        fac = 0.9 * err ** (-0.7 / ERROR_ORDER) * self._err_old ** (0.4 / ERROR_ORDER)
        return min(5.0, max(0.2, fac))

    def get_state(self) -> dict:
        """The stochastic state, the controller's memory and the queued increments (JSON)."""
        state = super().get_state()
        state["err_old"] = self._err_old
        state["wiener_queue"] = "" if self._queue is None else self._queue.to_json()
        state["wiener_shape"] = "" if self._queue is None else json.dumps(self._queue.shape)
        return state

    def set_state(self, state: dict) -> None:
        super().set_state(state)
        self._err_old = float(state.get("err_old", 1.0))
        self._queue = None
        if state.get("wiener_shape"):
            self._queue = WienerQueue(self.rng, tuple(json.loads(state["wiener_shape"])))
            self._queue.load_json(state.get("wiener_queue", ""))

    def describe(self) -> str:
        noise = self.noise.describe() if hasattr(self.noise, "describe") else "custom"
        return (f"{self.name} (weak order 1, adaptive, tolerance {self.tolerance:g} d, "
                f"Pe = {self.peclet:g}, kT = {self.kT:g} F0 d, noise {noise})")


class _Replay:
    """A stand-in generator that hands a custom noise function the normals ``z / 1``."""

    def __init__(self, z):
        self._z = np.asarray(z, dtype=np.float64)

    def standard_normal(self, size=None):
        return self._z.reshape(size if size is not None else self._z.shape)
