"""The flow map of the chain and the symmetries of a sedimenting ring.

A periodic state of a sedimenting knot repeats its shape after one period up to a
translation (it falls) and a rotation about the vertical axis (it turns slowly): it is a
*relative* periodic orbit of the group of translations and rotations about ``z`` that leave
the model unchanged (``docs/model.md``: gravity along ``-z``, every other force and the RPY
mobility depend only on bead separations). This module holds the two ingredients every
orbit computation needs:

* :class:`FlowMap`, ``phi_T(x)``: knotmm's own dynamics integrated over a time ``T`` with a
  fixed step on OpenMM's double-precision Reference platform. A fixed step makes
  ``phi_T`` a smooth function of ``x`` and ``T``, so Jacobian-vector products by finite
  differences (:meth:`FlowMap.jvp`) are accurate to ~1e-8; the CPU platform's single-precision
  forces and an adaptive step's discrete step choices would each add noise far above that.
* the symmetry operations: :func:`centre`, :func:`rotate_z`, :func:`rotation_generator`.

Positions are arrays of shape ``(n_beads, 3)`` in d; times in tau_d; angles in rad,
positive counterclockwise seen from above (gravity pointing down).
"""

from __future__ import annotations

import math
import time

import numpy as np

from knotmm.errors import ConfigError

__all__ = ["FlowMap", "centre", "make_flow", "rotate_z", "rotation_generator", "rms",
           "stable_step"]

#: Default fixed step of the flow map, tau_d (Heun; error ~2e-5 d per period of 6 tau_d at
#: N = 60, measured against steps of 0.005 and 0.02).
DEFAULT_STEP = 0.01
#: Heun is stable for ``h lambda <= 2`` on the negative real axis; the automatic step keeps
#: this margin below that limit.
STABILITY_MARGIN = 0.5
#: Size of the finite-difference perturbation in :meth:`FlowMap.jvp`, d rms per bead.
JVP_EPSILON = 1e-7


def rms(a) -> float:
    """Root mean square over beads of a per-bead vector field, shape (n_beads, 3) (d)."""
    a = np.asarray(a, dtype=float).reshape(-1, 3)
    return float(np.sqrt(np.mean(np.sum(a * a, axis=1))))


def centre(x: np.ndarray) -> np.ndarray:
    """``x`` with its centroid moved to the origin; shape (n_beads, 3), d."""
    return x - x.mean(axis=0)


def rotate_z(x: np.ndarray, angle: float) -> np.ndarray:
    """Rotate positions (or vectors) by ``angle`` rad about the ``z`` axis through the origin.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
    angle : float
        Counterclockwise seen from above (from ``+z``), in rad.
    """
    c, s = math.cos(angle), math.sin(angle)
    out = np.empty_like(x)
    out[:, 0] = c * x[:, 0] - s * x[:, 1]
    out[:, 1] = s * x[:, 0] + c * x[:, 1]
    out[:, 2] = x[:, 2]
    return out


def rotation_generator(x: np.ndarray) -> np.ndarray:
    """``e_z x r`` for every row: the velocity field of a unit-rate rotation about ``z``."""
    out = np.zeros_like(x)
    out[:, 0] = -x[:, 1]
    out[:, 1] = x[:, 0]
    return out


class FlowMap:
    """``phi_T(x)``: the chain's overdamped RPY dynamics over a time ``T``, fixed step.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        Any valid state of the chain (sets the number of beads and the starting Context).
    model : knotmm.model.parameters.ChainModel
        The physics (the run's ``[model]`` table).
    timestep : float
        The fixed step, in tau_d (Heun, order 2). The last step before ``T`` is shortened,
        so ``phi_T`` is continuous in ``T``.
    engine : {"auto", "plugin", "python"}
        ``"auto"``: the compiled plugin when it is available, else the Python integrators
        (same steps, same numbers up to rounding).
    threads : int
        Threads of the RPY pair loop.

    Attributes
    ----------
    n_flows : int
        Integrations over a period so far (the unit of cost of shooting and Floquet
        analysis).
    seconds : float
        Wall time spent integrating, in s.
    """

    def __init__(self, positions, model, timestep: float = DEFAULT_STEP, engine: str = "auto",
                 threads: int = 1):
        from knotmm.dynamics.deterministic import Heun
        from knotmm.engine.engines import PLUGIN, PYTHON
        from knotmm.engine.simulation import Simulation

        if not (isinstance(timestep, (int, float)) and 0 < timestep <= 0.05):
            raise ConfigError(
                f"timestep = {timestep!r}: the orbit's fixed step must be in (0, 0.05] tau_d "
                f"(Heun is unstable above ~0.04 for the default bond stiffness); try 0.01"
            )
        if engine == "auto":
            from knotmm import plugin

            engine = PLUGIN if plugin.available() else PYTHON
        if engine not in (PLUGIN, PYTHON):
            raise ConfigError(f"engine = {engine!r}: expected 'auto', 'plugin' or 'python'")
        self.model = model
        self.timestep = float(timestep)
        self.engine = engine
        self.sim = Simulation(np.asarray(positions, dtype=float), model, Heun(self.timestep),
                              platform="Reference", mobility_threads=threads, engine=engine)
        self.n_beads = self.sim.n_beads
        self.n_flows = 0
        self.seconds = 0.0

    def _start(self, x: np.ndarray) -> None:
        self.sim.set_positions(x)
        self.sim.time = 0.0
        self.sim.currentStep = 0

    def __call__(self, x: np.ndarray, period: float) -> np.ndarray:
        """``phi_T(x)``, shape (n_beads, 3), in d (true positions: the chain has fallen).

        Raises
        ------
        knotmm.errors.SimulationFault
            When the state breaks on the way (a bond past ``run.max_bond_length``).
        """
        if not period > 0:
            raise ConfigError(f"period = {period!r}: must be > 0 (in tau_d)")
        t0 = time.perf_counter()
        self._start(np.asarray(x, dtype=float).reshape(self.n_beads, 3))
        try:
            self.sim.run(float(period), write_at_start=False)
        finally:
            self.n_flows += 1
            self.seconds += time.perf_counter() - t0
        return self.sim.positions.copy()

    def trajectory(self, x: np.ndarray, period: float, n_frames: int) -> np.ndarray:
        """States at ``k T / n_frames``, ``k = 0 .. n_frames``; shape (n_frames + 1, n_beads, 3)."""
        self._start(np.asarray(x, dtype=float).reshape(self.n_beads, 3))
        frames = [self.sim.positions.copy()]
        for k in range(1, n_frames + 1):
            self.sim.run(k * period / n_frames - self.sim.time, write_at_start=False)
            frames.append(self.sim.positions.copy())
        return np.array(frames)

    def velocity(self, x: np.ndarray) -> np.ndarray:
        """``mu(x) F(x)``, shape (n_beads, 3), in d/tau_d."""
        return self.sim.velocity(np.asarray(x, dtype=float).reshape(self.n_beads, 3))

    def jvp(self, x: np.ndarray, period: float, base: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``D phi_T(x) v`` by a forward difference, shape (n_beads, 3).

        Parameters
        ----------
        x : ndarray, shape (n_beads, 3)
        period : float
        base : ndarray, shape (n_beads, 3)
            ``phi_T(x)``, already computed.
        v : ndarray, shape (n_beads, 3) or (3 n_beads,)
            The direction (any scale; the step is :data:`JVP_EPSILON` d rms per bead).
        """
        v = np.asarray(v, dtype=float).reshape(self.n_beads, 3)
        size = rms(v)
        if size == 0:
            return np.zeros_like(v)
        eps = JVP_EPSILON / size
        return (self(x + eps * v, period) - base) / eps


def stable_step(flow: FlowMap, x: np.ndarray, largest: float = DEFAULT_STEP,
                iterations: int = 40, seed: int = 0) -> tuple[float, float]:
    """A fixed step that keeps Heun stable at ``x``, and the stiffness it comes from.

    The Jacobian of ``v(x) = mu(x) F(x)`` is ``-mu H`` (``H`` the Hessian of the energy),
    similar to a symmetric matrix, so its eigenvalues are real; the largest in size,
    ``lambda`` (1/tau_d), comes from ``iterations`` rounds of
    :func:`knotmm.dynamics.deterministic.power_iteration`. Heun is stable for
    ``h lambda <= 2``; the step returned is ``min(largest, 2 STABILITY_MARGIN / lambda)``.

    Returns
    -------
    step, stiffness : float
        In tau_d and 1/tau_d.
    """
    from knotmm.dynamics.deterministic import power_iteration

    x = np.asarray(x, dtype=float)
    start = np.random.default_rng(seed).standard_normal(x.shape)
    lam, _ = power_iteration(flow.velocity, x, flow.velocity(x), start, iterations, rtol=0.0)
    if not lam > 0:
        return float(largest), 0.0
    return float(min(largest, 2 * STABILITY_MARGIN / lam)), lam


def make_flow(positions, model, timestep: float | None = None, engine: str = "auto",
              threads: int = 1) -> FlowMap:
    """A :class:`FlowMap` with the given fixed step, or (``None``) a stable one at ``positions``.

    The automatic step is :func:`stable_step` at ``positions`` (at most
    :data:`DEFAULT_STEP`), rounded down to two significant digits so that it reads well in
    ``orbit.json``.
    """
    flow = FlowMap(positions, model, timestep=timestep or DEFAULT_STEP, engine=engine,
                   threads=threads)
    if timestep is not None:
        return flow
    step, _ = stable_step(flow, positions)
    if step >= DEFAULT_STEP:
        return flow
    digits = 10.0 ** (math.floor(math.log10(step)) - 1)
    step = float(f"{math.floor(step / digits) * digits:.2g}")
    return FlowMap(positions, model, timestep=step, engine=engine, threads=threads)
