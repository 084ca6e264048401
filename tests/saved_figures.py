"""The matplotlib figures a piece of code saves, as it saves them (for tests that read what
a figure draws: ``drawn_text.py``, ``drawn_segments.py``)."""

from __future__ import annotations

from contextlib import contextmanager

import pytest
from matplotlib.figure import Figure


@contextmanager
def saved_figures():
    """Within the block, every ``Figure.savefig`` call still writes its file and the figure
    is appended to the list this yields, in the order saved."""
    captured: list[Figure] = []
    original = Figure.savefig

    def keep(fig, *args, **kwargs):
        captured.append(fig)
        return original(fig, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", keep)
        yield captured
