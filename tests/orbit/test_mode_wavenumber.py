"""Each part of a mode carries its own azimuthal wavenumber (issue 24, item 4).

The modes are built from parts whose wavenumbers are known by construction: a rigid tilt
about a horizontal axis (vertical displacement ``y_i``, one wave around the ring) and an
out-of-plane wave ``cos(m phi)``; their shares of ``|v|^2`` are set by the amplitudes.
"""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.orbit.modes import describe_mode


@pytest.fixture
def ring():
    n = 60
    phi = 2 * np.pi * np.arange(n) / n
    x = np.column_stack([5 * np.cos(phi), 5 * np.sin(phi), np.zeros(n)])
    return x, phi


def _mix(x, phi, tilt_share, m_wave):
    """Unit tilt about x plus a vertical cos(m phi) wave, scaled to the given shares."""
    tilt = np.cross([1.0, 0.0, 0.0], x)  # (0, -z, y): vertical displacement y_i
    wave = np.zeros_like(x)
    wave[:, 2] = np.cos(m_wave * phi)
    tilt /= np.linalg.norm(tilt)
    wave /= np.linalg.norm(wave)
    return np.sqrt(tilt_share) * tilt + np.sqrt(1 - tilt_share) * wave


def test_tilt_mode_names_the_tilts_wavenumber_not_the_leftovers(ring):
    x, phi = ring
    shape = describe_mode(x, _mix(x, phi, 0.89, 2))
    assert shape.label == "tilt"
    assert shape.tilt == pytest.approx(0.89, abs=1e-9)
    assert shape.out_of_plane == pytest.approx(0.11, abs=1e-9)
    assert shape.m == 1  # a rigid tilt is one wave around, whatever the leftover is
    assert shape.wavenumbers["tilt"] == 1
    assert shape.wavenumbers["out_of_plane"] == 2
    text = shape.describe()
    assert text.startswith("tilt m = 1:")
    assert "tilt 89 % (m = 1)" in text
    assert "out-of-plane 11 % (m = 2)" in text


def test_deformation_mode_with_a_small_tilt_names_the_deformations_wavenumber(ring):
    x, phi = ring
    shape = describe_mode(x, _mix(x, phi, 0.2, 3))
    assert shape.label == "out-of-plane"
    assert shape.m == 3
    assert shape.wavenumbers == {"tilt": 1, "out_of_plane": 3}
    assert "out-of-plane 80 % (m = 3)" in shape.describe()
    assert "tilt 20 % (m = 1)" in shape.describe()


def test_parts_without_power_get_no_wavenumber(ring):
    x, phi = ring
    v = np.zeros_like(x)
    v[:, 2] = np.sin(4 * phi)
    shape = describe_mode(x, v)
    assert shape.wavenumbers == {"out_of_plane": 4}
    assert shape.describe() == ("out-of-plane m = 4: tilt 0 %, out-of-plane 100 % (m = 4), "
                                "in-plane radial 0 %, tangential 0 %")
