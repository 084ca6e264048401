"""The bead-spring model: its parameters, its forces, its System and its Topology.

:mod:`~knotmm.model.parameters` (:class:`ChainModel`), :mod:`~knotmm.model.forces` (one
function per named ``openmm.Force``), :mod:`~knotmm.model.system` (:func:`chain_system`),
:mod:`~knotmm.model.topology` (:func:`bead_topology`, the one bead Topology). See
``docs/model.md`` and ``docs/architecture.md``.
"""
