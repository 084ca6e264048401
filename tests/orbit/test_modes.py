"""The mode description on modes whose shape is known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.orbit.modes import describe_mode


@pytest.fixture
def ring():
    n = 48
    phi = 2 * np.pi * np.arange(n) / n
    return np.column_stack([5 * np.cos(phi), 5 * np.sin(phi), 0.3 * np.sin(3 * phi)]), phi


def test_rigid_tilt_is_tilt(ring):
    x, _ = ring
    v = np.cross([1.0, 0.0, 0.0], x)  # a rotation about the x axis
    shape = describe_mode(x, v)
    assert shape.label == "tilt"
    assert shape.tilt == pytest.approx(1.0, abs=1e-9)


def test_uniform_radial_is_breathing(ring):
    x, _ = ring
    v = x.copy()
    v[:, 2] = 0.0
    shape = describe_mode(x, v)
    assert shape.label == "breathing"
    assert shape.m == 0
    assert shape.radial > 0.95


def test_out_of_plane_wave_has_its_wavenumber(ring):
    x, phi = ring
    v = np.zeros_like(x)
    v[:, 2] = np.cos(2 * phi)
    shape = describe_mode(x, v)
    assert shape.label == "out-of-plane"
    assert shape.m == 2
    assert shape.out_of_plane > 0.95


def test_tangential_wave_is_sliding_and_complex_modes_use_both_parts(ring):
    x, phi = ring
    t = np.column_stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)])
    v = t * np.cos(3 * phi)[:, None]
    w = t * np.sin(3 * phi)[:, None]
    shape = describe_mode(x, v + 1j * w)
    assert shape.label == "sliding"
    assert shape.m == 3
    assert shape.tangential > 0.95


def test_spin_and_translation_are_not_deformation(ring):
    x, _ = ring
    v = np.cross([0.0, 0.0, 1.0], x) + np.array([0.0, 0.0, 1.0])
    shape = describe_mode(x, v)
    assert shape.rigid_other == pytest.approx(1.0, abs=1e-9)
