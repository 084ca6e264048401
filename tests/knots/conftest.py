"""Shared helpers of the knot tests."""

from __future__ import annotations

import numpy as np
import pytest


def _torus_curve(p, q, n, r0=3.0, a=1.0):
    """The study's torus-knot parametrisation sampled at equal parameter steps."""
    alpha = np.linspace(0.0, 2.0 * np.pi * p, n, endpoint=False)
    rho = r0 + a * np.sin(q * alpha / p)
    return np.c_[rho * np.cos(alpha), rho * np.sin(alpha), a * np.cos(q * alpha / p)]


@pytest.fixture(scope="session")
def torus_curve():
    """``torus_curve(p, q, n, r0=3, a=1)``: the T(p,q) curve at ``n`` equal parameter steps."""
    return _torus_curve
