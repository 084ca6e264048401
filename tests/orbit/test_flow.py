"""Symmetry operations and the flow map, against closed forms and naive versions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from knotmm.orbit.flow import centre, rms, rotate_z, rotation_generator
from knotmm.orbit.shooting import best_rotation


def test_rotate_z_is_the_rotation_matrix(rng):
    x = rng.standard_normal((7, 3))
    a = 0.83
    m = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    np.testing.assert_allclose(rotate_z(x, a), x @ m.T, atol=1e-15)
    np.testing.assert_allclose(rotate_z(rotate_z(x, a), -a), x, atol=1e-14)


def test_rotation_generator_is_the_derivative_of_the_rotation(rng):
    x = rng.standard_normal((5, 3))
    h = 1e-6
    fd = (rotate_z(x, h) - rotate_z(x, -h)) / (2 * h)
    np.testing.assert_allclose(rotation_generator(x), fd, atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 0.3, -1.2, 3.0])
def test_best_rotation_recovers_a_known_turn(rng, angle):
    b = centre(rng.standard_normal((20, 3)))
    a = rotate_z(b, angle)
    assert best_rotation(a, b) == pytest.approx(angle, abs=1e-12)
    # a little noise moves it little
    noisy = a + 1e-4 * rng.standard_normal(a.shape)
    assert best_rotation(noisy, b) == pytest.approx(angle, abs=1e-3)


def test_rms_is_per_bead():
    v = np.zeros((4, 3))
    v[:, 0] = 2.0
    assert rms(v) == pytest.approx(2.0)
    assert rms(v.ravel()) == pytest.approx(2.0)


def test_flow_map_is_equivariant_and_smooth(orbit40):
    """phi_T commutes with rotations about z and translations (the model's symmetries), and
    the finite-difference JVP is linear in the direction."""
    flow, orbit, _ = orbit40
    x, t = orbit.positions, 1.0
    end = flow(x, t)
    turned = flow(rotate_z(x, 0.7) + np.array([1.0, -2.0, 3.0]), t)
    np.testing.assert_allclose(turned, rotate_z(end, 0.7) + np.array([1.0, -2.0, 3.0]),
                               atol=1e-9)
    v = np.random.default_rng(1).standard_normal(x.shape)
    j1 = flow.jvp(x, t, end, v)
    j2 = flow.jvp(x, t, end, 2.0 * v)
    np.testing.assert_allclose(j2, 2.0 * j1, rtol=1e-5, atol=1e-6 * np.abs(j1).max())


def test_stable_step_matches_the_stiffest_bond_mode():
    """The power iteration's stiffness equals the largest eigenvalue of a dense Jacobian of
    the velocity built column by column in the test (a flat ring of 8 beads)."""
    from reference_model import dense_jacobian, flat_ring

    from knotmm.model.parameters import ChainModel
    from knotmm.orbit.flow import FlowMap, stable_step

    x = flat_ring(8)
    flow = FlowMap(x, ChainModel(gravity=0.0), engine="python")
    step, lam = stable_step(flow, x, iterations=200)
    jac = dense_jacobian(flow.velocity, x)
    largest = np.max(np.abs(np.linalg.eigvals(jac)))
    assert lam == pytest.approx(largest, rel=1e-3)
    assert step == pytest.approx(min(0.01, 1.0 / largest), rel=1e-9)
