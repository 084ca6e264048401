"""Floquet multipliers of a relative periodic orbit, by Arnoldi on the monodromy operator.

On the orbit ``x`` (period ``T``, rotation ``theta``) the monodromy operator is the
linearised return map in the co-rotating frame,

    M v = R_z(-theta) Dphi_T(x) v ,      v in R^(3N),

applied by finite differences of the flow map. Five of its eigenvalues come from the
model's symmetries and are neutral: the three translations (``z``: multiplier 1; ``x`` and
``y``: ``exp(-+i theta)``, which have modulus 1 because the frame turns by ``theta`` per
period), the rotation about ``z`` (1) and the shift in time along the orbit (1). Their span
``S`` is invariant under ``M`` (equivariance of the flow), so the spectrum of ``M`` is the
spectrum of ``M`` on ``S`` (:attr:`FloquetResult.neutral`, from the 5 x 5 matrix
``Q^T M Q``, ``Q`` an orthonormal basis of ``S``) together with the spectrum of the quotient,
which is that of ``(I - Q Q^T) M (I - Q Q^T)`` apart from five zeros. ARPACK's implicitly
restarted Arnoldi method (``scipy.sparse.linalg.eigs``) finds the leading quotient
multipliers: these are the ones that decide stability.

A multiplier ``mu`` outside the unit circle grows a perturbation by ``|mu|`` per period; the
leading exponent ``ln |mu_1| / T`` (1/tau_d) is its rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

from knotmm.errors import ConfigError
from knotmm.orbit.flow import centre, rotate_z, rotation_generator

__all__ = ["FloquetResult", "NEUTRAL_NAMES", "floquet", "monodromy"]

#: The symmetry of each neutral multiplier, in the order :func:`floquet` reports them.
NEUTRAL_NAMES = ("translation z", "translation x, y (co-rotating frame)",
                 "translation x, y (co-rotating frame)", "rotation about z", "time shift")


@dataclass
class FloquetResult:
    """Leading Floquet multipliers of an orbit.

    Attributes
    ----------
    multipliers : ndarray, shape (k,), complex
        The leading non-neutral multipliers, by decreasing modulus.
    modes : ndarray, shape (k, n_beads, 3), complex
        Their eigenvectors (unit Euclidean norm), in d.
    neutral : ndarray, shape (5,), complex
        The multipliers of the symmetry subspace.
    neutral_names : list of str
        The symmetry each neutral multiplier's eigenvector is mostly made of.
    period : float
        The orbit's period, tau_d.
    n_flows : int
        Flow integrations spent.
    converged : bool
        Whether ARPACK converged all ``k`` (if not, the converged ones are kept).
    """

    multipliers: np.ndarray
    modes: np.ndarray
    neutral: np.ndarray
    neutral_names: list
    period: float
    n_flows: int
    converged: bool = True

    @property
    def leading_exponent(self) -> float:
        """``ln |mu_1| / T``, in 1/tau_d (> 0: unstable)."""
        if self.multipliers.size == 0:
            return math.nan
        return float(math.log(abs(self.multipliers[0])) / self.period)

    @property
    def n_unstable(self) -> int:
        """Multipliers outside the unit circle (non-neutral)."""
        return int(np.sum(np.abs(self.multipliers) > 1.0))


def symmetry_vectors(flow, x: np.ndarray) -> np.ndarray:
    """The symmetry directions at ``x``, shape (5, n_beads, 3).

    In this order: translations along x, y, z, the rotation about z, the time shift.
    """
    n = x.shape[0]
    out = np.zeros((5, n, 3))
    for axis in range(3):
        out[axis, :, axis] = 1.0
    out[3] = rotation_generator(centre(x))
    out[4] = flow.velocity(x)
    return out


def monodromy(flow, orbit):
    """``M`` as a function ``v (3N,) -> M v (3N,)``."""
    x, period, rotation = orbit.positions, orbit.period, orbit.rotation
    end = flow(x, period)

    def apply(v):
        return rotate_z(flow.jvp(x, period, end, v), -rotation).ravel()

    return apply


def floquet(flow, orbit, k: int = 10, tolerance: float = 1e-6, seed: int = 0) -> FloquetResult:
    """The ``k`` leading non-neutral Floquet multipliers of ``orbit`` and the neutral five.

    Parameters
    ----------
    flow : knotmm.orbit.flow.FlowMap
        The flow map the orbit was converged with.
    orbit : knotmm.orbit.shooting.Orbit
    k : int
        Number of non-neutral multipliers (``1 <= k <= 3 n_beads - 8``).
    tolerance : float
        ARPACK's relative accuracy of the eigenvalues.
    seed : int
        Seed of ARPACK's starting vector (so the result is reproducible).

    Returns
    -------
    FloquetResult
    """
    x = orbit.positions
    n3 = x.size
    if not 1 <= int(k) <= n3 - 8:
        raise ConfigError(f"modes = {k!r}: expected 1 .. {n3 - 8} for {x.shape[0]} beads")
    start = flow.n_flows
    apply = monodromy(flow, orbit)
    gens = symmetry_vectors(flow, x).reshape(5, n3)
    q, _ = np.linalg.qr(gens.T)  # (3N, 5), orthonormal basis of S
    mq = np.column_stack([apply(q[:, j]) for j in range(5)])
    # Q's columns follow the generators' order (translations, rotation, time shift), and M
    # maps translations to translations, the rotation to itself plus translations, the time
    # shift to itself: Q^T M Q is block upper triangular and its diagonal blocks give the
    # multiplier of each symmetry (no splitting of the repeated multiplier 1).
    block = q.T @ mq
    translations = np.linalg.eigvals(block[:3, :3])
    order = np.argsort(np.abs(translations.imag), kind="stable")
    neutral = np.concatenate([translations[order], [block[3, 3], block[4, 4]]])

    def quotient(v):
        v = np.asarray(v, dtype=float).ravel()
        v = v - q @ (q.T @ v)
        out = apply(v)
        return out - q @ (q.T @ out)

    op = LinearOperator((n3, n3), matvec=quotient, dtype=float)
    v0 = np.random.default_rng(seed).standard_normal(n3)
    v0 -= q @ (q.T @ v0)
    ncv = min(n3 - 1, max(2 * k + 1, 20))
    converged = True
    try:
        values, vectors = eigs(op, k=k, which="LM", v0=v0, ncv=ncv, tol=tolerance)
    except ArpackNoConvergence as exc:
        values, vectors, converged = exc.eigenvalues, exc.eigenvectors, False
    order = np.argsort(-np.abs(values), kind="stable")
    values = values[order]
    vectors = vectors[:, order].T.reshape(len(values), x.shape[0], 3)
    return FloquetResult(
        multipliers=values,
        modes=vectors,
        neutral=neutral,
        neutral_names=list(NEUTRAL_NAMES),
        period=orbit.period,
        n_flows=flow.n_flows - start,
        converged=converged,
    )
