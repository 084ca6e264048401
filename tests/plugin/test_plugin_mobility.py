"""The plugin's RPY velocities against a naive numpy RPY written here from docs/model.md.

One Euler step of size h under constant forces F moves the beads by exactly ``h mu(r) F``:
the step's displacement divided by h is the plugin's velocity.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from plugin_helpers import plugin_context, positions_of

from knotmm.plugin import RPYIntegrator


def naive_rpy(x, d=1.0, mu0=1.0):
    """Dense 3N x 3N RPY tensor, bead-major, from docs/model.md's three cases (pair by pair)."""
    n = len(x)
    m = np.zeros((3 * n, 3 * n))
    eye = np.eye(3)
    for i in range(n):
        for j in range(n):
            if i == j:
                block = eye
            else:
                rvec = x[i] - x[j]
                r = np.linalg.norm(rvec)
                rr = np.outer(rvec, rvec) / r**2
                if r >= d:
                    block = 3 * d / (8 * r) * ((1 + d**2 / (6 * r**2)) * eye
                                               + (1 - d**2 / (2 * r**2)) * rr)
                else:
                    block = (1 - 9 * r / (16 * d)) * eye + (3 * r / (16 * d)) * rr
            m[3 * i:3 * i + 3, 3 * j:3 * j + 3] = mu0 * block
    return m


def constant_force_system(forces):
    """Beads (unit mass) pushed by the constant forces (shape (n, 3), kJ/mol/nm)."""
    system = openmm.System()
    f = openmm.CustomExternalForce("-(fx*x + fy*y + fz*z)")
    for name in ("fx", "fy", "fz"):
        f.addPerParticleParameter(name)
    for i, fi in enumerate(forces):
        system.addParticle(1.0)
        f.addParticle(i, [float(c) for c in fi])
    system.addForce(f)
    return system


def plugin_velocity(x, forces, h=1.0, **kwargs):
    integ = RPYIntegrator(h, "euler", **kwargs)
    ctx = plugin_context(constant_force_system(forces), x, integ)
    integ.step(1)
    return (positions_of(ctx) - x) / h


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(("d", "mu0"), [(1.0, 1.0), (0.7, 2.5)])
def test_velocities_match_naive_rpy(seed, d, mu0):
    rng = np.random.default_rng(seed)
    n = 25
    # a box of 2.5 d: about a third of the pairs overlap (r < d), the rest do not
    x = rng.uniform(-1.25, 1.25, size=(n, 3)) * d
    forces = rng.standard_normal((n, 3))
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)[np.triu_indices(n, 1)]
    assert (r < d).sum() > 20 and (r >= d).sum() > 20
    expected = (naive_rpy(x, d, mu0) @ forces.reshape(-1)).reshape(n, 3)
    got = plugin_velocity(x, forces, bead_diameter=d, mobility=mu0)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-13)


def test_pairs_at_and_near_contact():
    """Both branches meet at r = d, and the far branch holds far away."""
    for r in (0.0 + 1e-9, 0.3, 1.0 - 1e-12, 1.0, 1.0 + 1e-12, 1.7, 40.0):
        x = np.array([[0.0, 0.0, 0.0], [r, 0.2 * r, -0.1 * r]])
        forces = np.array([[0.3, -1.0, 0.5], [1.0, 0.2, -0.7]])
        expected = (naive_rpy(x) @ forces.reshape(-1)).reshape(2, 3)
        np.testing.assert_allclose(plugin_velocity(x, forces), expected, rtol=1e-12, atol=1e-13)


def test_single_bead_falls_at_mu0_f():
    """A lone bead under F moves mu0 F per unit time (docs/model.md: one d per tau_d under F0)."""
    x = np.zeros((1, 3))
    got = plugin_velocity(x, np.array([[0.0, 0.0, -1.0]]), h=0.25, mobility=1.0)
    np.testing.assert_allclose(got, [[0.0, 0.0, -1.0]], atol=1e-15)


def test_threads_give_the_same_velocities():
    rng = np.random.default_rng(7)
    n = 600
    x = rng.uniform(-5, 5, size=(n, 3))
    forces = rng.standard_normal((n, 3))
    one = plugin_velocity(x, forces, threads=1)
    two = plugin_velocity(x, forces, threads=2)
    np.testing.assert_array_equal(one, two)
    expected = (naive_rpy(x[:40]) @ forces[:40].reshape(-1)).reshape(40, 3)
    sub = plugin_velocity(x[:40], forces[:40], threads=2)
    np.testing.assert_allclose(sub, expected, rtol=1e-12, atol=1e-13)
