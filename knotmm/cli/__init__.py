"""The ``knotmm`` command line: :mod:`knotmm.cli.main` dispatches to one module per sub-command."""

from knotmm.cli.main import console_main, main

__all__ = ["console_main", "main"]
