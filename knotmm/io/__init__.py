"""The run directory and its files (``docs/architecture.md``).

Modules: :mod:`~knotmm.io.rundir` (file names, ``run.toml``, run status, preparing and
locking a directory), :mod:`~knotmm.io.dcd` (DCD layout, frame counts, truncation),
:mod:`~knotmm.io.observables` (``observables.csv``), :mod:`~knotmm.io.pdb` (the bead PDB),
:mod:`~knotmm.io.structure` (a start frame from a PDB or DCD), :mod:`~knotmm.io.run_data`
(:func:`~knotmm.io.run_data.load_run`), :mod:`~knotmm.io.atomic` (atomic writes).
"""
