"""Helpers of the plugin tests (their own module: tests/ and tests/plugin both have a conftest)."""

from __future__ import annotations

import numpy as np
import openmm


def plugin_context(system, positions, integrator, platform="Reference"):
    """An OpenMM Context on ``platform`` (CPU: one thread) holding ``positions`` (in nm = d)."""
    plat = openmm.Platform.getPlatformByName(platform)
    props = {"Threads": "1"} if platform == "CPU" else {}
    ctx = openmm.Context(system, integrator, plat, props)
    ctx.setPositions(np.asarray(positions, dtype=np.float64))
    return ctx


def positions_of(ctx) -> np.ndarray:
    """The Context's positions, shape (n_particles, 3), float64, in nm."""
    return ctx.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(
        openmm.unit.nanometer
    )


def dimer_system(k, l0):
    """Two beads and a harmonic bond ``k/2 (r - l0)^2`` (k in kJ/mol/nm^2, l0 in nm)."""
    system = openmm.System()
    for _ in range(2):
        system.addParticle(1.0)
    bond = openmm.HarmonicBondForce()
    bond.addBond(0, 1, l0, k)
    system.addForce(bond)
    return system


def checkpoint_round_trip(ctx, integrator, saved_at: float, end: float):
    """Step to ``saved_at``, checkpoint, step to ``end``; load the checkpoint and step to
    ``end`` again. Returns (the checkpoint, the first positions at ``end``, the second)."""
    integrator.stepTo(saved_at)
    saved = ctx.createCheckpoint()
    integrator.stepTo(end)
    first = positions_of(ctx)
    ctx.loadCheckpoint(saved)
    integrator.stepTo(end)
    return saved, first, positions_of(ctx)
