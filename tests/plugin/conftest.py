"""Shared helpers of the plugin tests: skip them all cleanly when the plugin is not built."""

from __future__ import annotations

import pytest

import knotmm.plugin as kp

requires_plugin = pytest.mark.skipif(not kp.available(), reason=str(kp.load_error()))


def pytest_collection_modifyitems(config, items):
    for item in items:
        in_here = "tests/plugin/" in str(item.fspath).replace("\\", "/")
        if in_here and getattr(item.module, "NEEDS_PLUGIN", True):
            item.add_marker(requires_plugin)

