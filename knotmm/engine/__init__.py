"""The engine: a Simulation that owns its state, and its reporters (``docs/architecture.md``).

Modules: :mod:`~knotmm.engine.simulation` (:class:`~knotmm.engine.simulation.Simulation`,
``from_config``, ``saveCheckpoint``/``loadCheckpoint``), :mod:`~knotmm.engine.base` (the
engine interface, :class:`~knotmm.engine.base.Engine`), :mod:`~knotmm.engine.engines` (which
engine runs, ``make_engine``), :mod:`~knotmm.engine.python_engine` and
:mod:`~knotmm.engine.plugin_engine` (the two engines), :mod:`~knotmm.engine.schedule`
(the one scheduler of time-scheduled reporters, and the landing rule),
:mod:`~knotmm.engine.reporters` (trajectory, observables, progress, knot checks),
:mod:`~knotmm.engine.checkpoint` (the checkpoint file and its reporter),
:mod:`~knotmm.engine.interrupt` (stopping between steps).
"""
