"""Dynamics: the numerics of the overdamped chain (no OpenMM, no run files).

* :mod:`knotmm.dynamics.mobility`: the Rotne-Prager-Yamakawa mobility (numba pair loop).
* :mod:`knotmm.dynamics.deterministic`: time steppers of ``dr/dt = mu(r) F(r)`` (``Pe = inf``).
* :mod:`knotmm.dynamics.noise`: thermal noise with covariance ``mu`` (Cholesky, Lanczos) and
  the noise stream's state.
* :mod:`knotmm.dynamics.brownian`: time steppers of the Ito equation at finite Peclet number.
* :mod:`knotmm.dynamics.registry`: the ONE table of integrator names (order, adaptive or not,
  Brownian or not, default step), the ``"auto"`` policy and construction from a run file.

Goal of this layout: adding an integrator touches one registry (an entry in
:data:`knotmm.dynamics.registry.REGISTRY`) and one module (its class). The equations and
units are in ``docs/model.md``; the layering in ``docs/architecture.md``.
"""
