"""``python -m knotmm``: the same as the ``knotmm`` command (and ``python -m knotmm.cli``)."""

import sys

try:
    from knotmm.cli.main import console_main
except KeyboardInterrupt:  # Ctrl-C while the command line is still importing
    sys.exit(130)

sys.exit(console_main())
