"""``python -m knotmm.cli``: the same as the ``knotmm`` command."""

import sys

from knotmm.cli.main import console_main

sys.exit(console_main())
