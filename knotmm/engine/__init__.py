"""The engine: a Simulation that owns its state, and its reporters (``docs/architecture.md``).

Modules: :mod:`~knotmm.engine.simulation` (:class:`~knotmm.engine.simulation.Simulation`,
``from_config``, ``saveCheckpoint``/``loadCheckpoint``), :mod:`~knotmm.engine.schedule`
(the one scheduler of time-scheduled reporters), :mod:`~knotmm.engine.reporters`
(trajectory, observables, progress, knot checks), :mod:`~knotmm.engine.checkpoint` (the
checkpoint file and its reporter), :mod:`~knotmm.engine.interrupt` (stopping between steps).
"""
