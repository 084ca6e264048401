"""Shared fixtures of the engine tests (kept small: see reference_model.py for the physics)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# Test modules live in folders that mirror the package; the shared reference model
# (tests/reference_model.py) is imported by name from any of them.
sys.path.insert(0, str(Path(__file__).parent))

# Property-based tests draw the same examples on every run by default, so that CI cannot fail
# by chance on code that did not change; HYPOTHESIS_PROFILE=explore draws fresh ones.
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture
def rng():
    """A fresh seeded generator per test (reproducible, independent of test order)."""
    return np.random.default_rng(20181127)


@pytest.fixture(scope="session")
def trefoil40():
    """The T(2,3) template with 40 beads, in d (centred, bonds 0.6 d)."""
    from knotmm.shapes import torus_knot

    return torus_knot(2, 3, 40)


@pytest.fixture(scope="session")
def trefoil90():
    """The T(2,3) template with 90 beads (the default run's start), in d."""
    from knotmm.shapes import torus_knot

    return torus_knot(2, 3, 90)
