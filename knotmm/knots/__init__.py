"""Knot identity: writhe, knot type (topoly, in an isolated worker process), chirality.

* :mod:`knotmm.knots.writhe`: the writhe of a closed chain (exact Gauss integral, numba).
* :mod:`knotmm.knots.chirality`: the one vocabulary of knot types (``"+3_1"``, ``"-3_1"``,
  ``"4_1"``, ``"0_1"``, ``"unknown"``) and handedness (``"right"``, ``"left"``,
  ``"achiral"``, ``"unknown"``).
* :mod:`knotmm.knots.identify`: :func:`~knotmm.knots.identify.identify_knot`, the one entry
  point for knot identification.
* :mod:`knotmm.knots.worker`: the worker process (``python -m knotmm.knots.worker``) where
  topoly runs, and its client.
* :mod:`knotmm.knots.homfly`: topoly's HOMFLY-PT call and its guards, imported only by the
  worker: no other knotmm process imports topoly (``docs/architecture.md``).
* :mod:`knotmm.knots.topoly_import`: the worker's import of topoly without the plotting
  libraries its package loads (0.4 s against 1.4-2 s).
"""
