"""Sub-commands of the ``knotmm`` command line, one module each."""
