"""Two analysis.json-like values compared leaf by leaf (floats to 1e-12, the rest exactly)."""

from __future__ import annotations

import pytest


def assert_same_values(a, b, path: str = "") -> None:
    """``a`` and ``b`` (nested dicts, lists, numbers, strings) are equal: the same keys and
    lengths, floats to 1e-12 relative (1e-14 absolute), the rest exactly; ``path`` names
    where a difference is."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            assert_same_values(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for k, (u, v) in enumerate(zip(a, b, strict=True)):
            assert_same_values(u, v, f"{path}[{k}]")
    elif isinstance(a, float):
        assert b == pytest.approx(a, rel=1e-12, abs=1e-14), path
    else:
        assert a == b, path
