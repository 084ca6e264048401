"""Force layouts, platforms and thread placements of knotmm's System, for ``bench_forces.py
layouts``: what one evaluation costs inside a run, and whether a variant keeps the forces.

Variants (:data:`VARIANTS`; ``NAME@pin``: any of them with the calling thread and OpenMM's
pool thread on one core, :class:`harness.Pinned`, only where the threads run changes):

* ``current``: knotmm's System (``chain_system``) on the platform a run uses (CPU, one thread).
* ``cpu-2threads``, ``cpu-deterministic``: the same System, CPU platform with ``Threads = 2``
  or ``DeterministicForces = true``.
* ``one-group``: the four forces in force group 0 (same Forces, same order).
* ``reference``: the same System on the Reference platform (double precision, no thread pool).
* ``*-cnb``: the steric term as a ``CustomNonbondedForce`` (cutoff ``rc``, bonded pairs
  excluded) instead of ``NonbondedForce``; ``*-cnb-wide``: the same with a 2 d cutoff and
  ``step(rc - r)`` in the expression (the CPU platform's padding is a quarter of the cutoff,
  so its neighbour list is rebuilt less often); ``*-cnb-nocutoff``: all pairs, no neighbour
  list, truncated by ``step(rc - r)``; ``*-pairs``: a ``CustomBondForce`` over every
  non-bonded pair (no neighbour list either).
* ``*-compound``: bonds, bending and gravity as one ``CustomCompoundBondForce`` over the
  triples (i-1, i, i+1) (three Forces fewer; same energy function).
* ``cpu-harmonic-angle``: the bending as ``HarmonicAngleForce`` (a CPU-platform kernel, one
  more hand-off to the thread pool) instead of the ``CustomAngleForce`` (a Reference kernel).
* ``*-nosteric``, ``*-noforce``: for the breakdown only (not the model): the System without
  its steric force, and a System with no force at all (its cost is OpenMM's fixed cost per
  call + the RPY mobility; the chain does not move, so a fixed number of Euler steps is
  timed instead).

:func:`time_variant` times one stretch of the plugin's rk23 (tolerance 1e-4 d, as ``knotmm
run``) from the template in a fresh Context: wall time of ``stepTo`` over the evaluations it
made (``getNumForceEvaluations``), so the beads move from call to call as in a run.
:func:`check_forces` compares each variant's forces with the current System's on the
Reference platform (shapes along the run and thin-tube shapes with steric contacts) and with
central differences of its own energy; :func:`check_bits` compares positions after the run.
"""

from __future__ import annotations

import time

import numpy as np
import openmm
from harness import Pinned

from knotmm.model.layout import ChainLayout
from knotmm.model.system import chain_system
from knotmm.shapes import torus_knot

CPU1 = ("CPU", {"Threads": "1"})
REF = ("Reference", {})


# -- Systems --------------------------------------------------------------------------------
def _particles(n):
    system = openmm.System()
    for _ in range(n):
        system.addParticle(1.0)
    return system


def _replace(system, name, new):
    """``system`` with its force called ``name`` replaced by ``new`` (same group, same place)."""
    out = _particles(system.getNumParticles())
    for k in range(system.getNumForces()):
        force = system.getForce(k)
        if force.getName() == name:
            if new is None:
                continue
            new.setName(name)
            new.setForceGroup(force.getForceGroup())
            out.addForce(new)
        else:
            out.addForce(openmm.XmlSerializer.clone(force))
    return out


def _nonbonded_pairs(n):
    bonded = {tuple(sorted(map(int, b))) for b in ChainLayout.ring(n).bonds()}
    return [(i, j) for i in range(n) for j in range(i + 1, n) if (i, j) not in bonded]


def _lj(model, truncate):
    expr = "eps*((sig/r)^12 - (sig/r)^6)"
    if truncate:
        expr = f"step({model.steric_range!r} - r)*{expr}"
    return expr + f"; eps={model.lj_epsilon!r}; sig={model.lj_sigma!r}"


def _cnb(n, model, method, cutoff, truncate):
    force = openmm.CustomNonbondedForce(_lj(model, truncate))
    force.setNonbondedMethod(method)
    force.setCutoffDistance(cutoff)
    force.setUseSwitchingFunction(False)
    force.setUseLongRangeCorrection(False)
    for _ in range(n):
        force.addParticle([])
    for i, j in ChainLayout.ring(n).bonds():
        force.addExclusion(int(i), int(j))
    return force


def system_cnb(x, model):
    n = len(x)
    return _replace(chain_system(x, model), "steric",
                    _cnb(n, model, openmm.CustomNonbondedForce.CutoffNonPeriodic,
                         model.steric_range, False))


def system_cnb_wide(x, model):
    n = len(x)
    return _replace(chain_system(x, model), "steric",
                    _cnb(n, model, openmm.CustomNonbondedForce.CutoffNonPeriodic, 2.0, True))


def system_cnb_nocutoff(x, model):
    n = len(x)
    return _replace(chain_system(x, model), "steric",
                    _cnb(n, model, openmm.CustomNonbondedForce.NoCutoff, 1.0, True))


def system_pairs(x, model):
    force = openmm.CustomBondForce(_lj(model, True))
    for i, j in _nonbonded_pairs(len(x)):
        force.addBond(i, j, [])
    return _replace(chain_system(x, model), "steric", force)


def system_compound(x, model):
    """bond (i, i+1) + bend at i + gravity on i as one three-particle term per bead."""
    n = len(x)
    force = openmm.CustomCompoundBondForce(
        3,
        f"0.5*{model.bond_stiffness!r}*(distance(p2, p3) - {model.bond_length!r})^2"
        f" + 0.5*{model.bending_stiffness!r}*(angle(p1, p2, p3) - {np.pi!r})^2"
        f" + {model.gravity!r}*z2",
    )
    for i in range(n):
        force.addBond([(i - 1) % n, i, (i + 1) % n], [])
    base = chain_system(x, model)
    out = _particles(n)
    out.addForce(force)
    for k in range(base.getNumForces()):
        f = base.getForce(k)
        if f.getName() == "steric":
            out.addForce(openmm.XmlSerializer.clone(f))
    return out


def system_harmonic_angle(x, model):
    n = len(x)
    force = openmm.HarmonicAngleForce()
    for i in range(n):
        force.addAngle((i - 1) % n, i, (i + 1) % n, np.pi, model.bending_stiffness)
    return _replace(chain_system(x, model), "bend", force)


def system_one_group(x, model):
    system = chain_system(x, model)
    for k in range(system.getNumForces()):
        system.getForce(k).setForceGroup(0)
    return system


def system_nosteric(x, model):
    return _replace(chain_system(x, model), "steric", None)


def system_noforce(x, model):
    return _particles(len(x))


#: name -> (System maker, platform, properties, pinned)
VARIANTS = {
    "current": (chain_system, *CPU1, False),
    "cpu-2threads": (chain_system, "CPU", {"Threads": "2"}, False),
    "cpu-deterministic": (chain_system, "CPU", {"Threads": "1", "DeterministicForces": "true"},
                          False),
    "one-group": (system_one_group, *CPU1, False),
    "cpu-cnb": (system_cnb, *CPU1, False),
    "cpu-cnb-wide": (system_cnb_wide, *CPU1, False),
    "cpu-cnb-nocutoff": (system_cnb_nocutoff, *CPU1, False),
    "cpu-pairs": (system_pairs, *CPU1, False),
    "cpu-compound": (system_compound, *CPU1, False),
    "cpu-harmonic-angle": (system_harmonic_angle, *CPU1, False),
    "cpu-nosteric": (system_nosteric, *CPU1, False),
    "cpu-noforce": (system_noforce, *CPU1, False),
    "reference": (chain_system, *REF, False),
    "ref-cnb": (system_cnb, *REF, False),
    "ref-cnb-nocutoff": (system_cnb_nocutoff, *REF, False),
    "ref-pairs": (system_pairs, *REF, False),
    "ref-compound": (system_compound, *REF, False),
    "ref-nosteric": (system_nosteric, *REF, False),
    "ref-noforce": (system_noforce, *REF, False),
}
DEFAULT = ["current", "current@pin", "cpu-2threads", "cpu-deterministic", "one-group",
           "cpu-cnb", "cpu-cnb@pin", "cpu-cnb-wide", "cpu-compound", "cpu-harmonic-angle",
           "cpu-harmonic-angle@pin", "cpu-nosteric", "cpu-nosteric@pin", "cpu-noforce",
           "cpu-noforce@pin", "reference", "ref-cnb-nocutoff", "ref-pairs", "ref-compound",
           "ref-nosteric", "ref-noforce"]


# -- timing ---------------------------------------------------------------------------------
def _integrator(method="rk23", step=0.01):
    from knotmm.plugin import RPYIntegrator

    return RPYIntegrator(step, method, 1e-4, threads=1)


def _variant(name):
    """(System maker, platform, properties, pinned) of ``name``; ``NAME@pin``: pinned."""
    base, _, suffix = name.partition("@")
    make, platform, props, pinned = VARIANTS[base]
    return make, platform, props, pinned or suffix == "pin"


def _context(name, x, model, method="rk23", step=0.01):
    make, platform, props, _ = _variant(name)
    integ = _integrator(method, step)
    context = openmm.Context(make(x, model), integ, openmm.Platform.getPlatformByName(platform),
                             props)
    context.setPositions(x)
    return context, integ


def time_variant(name, x, model, duration):
    """Seconds per evaluation of one timed stretch in a fresh Context, and the evaluations."""
    with Pinned(_variant(name)[3]):
        if name.partition("@")[0].endswith("noforce"):  # a chain that does not move:
            # a fixed number of Euler steps
            context, integ = _context(name, x, model, "euler", 1e-5)
            integ.step(5)
            calls = max(50, int(60 * duration))
            e0 = integ.getNumForceEvaluations()
            t0 = time.perf_counter()
            integ.step(calls)
        else:
            context, integ = _context(name, x, model)
            e0 = integ.getNumForceEvaluations()
            t0 = time.perf_counter()
            integ.stepTo(duration)
        wall = time.perf_counter() - t0
        evaluations = integ.getNumForceEvaluations() - e0
        del context
    return wall / evaluations, evaluations


def _forces(system, x, platform="Reference"):
    integ = openmm.VerletIntegrator(0.001)
    ctx = openmm.Context(system, integ, openmm.Platform.getPlatformByName(platform))
    ctx.setPositions(x)
    state = ctx.getState(getForces=True, getEnergy=True)
    f = state.getForces(asNumpy=True).value_in_unit(
        openmm.unit.kilojoule_per_mole / openmm.unit.nanometer)
    return np.asarray(f), state.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole)


def shapes_along_run(x, model, duration, count=4):
    """Positions at ``count`` times of the current System's run (CPU platform)."""
    context, integ = _context("current", x, model)
    out = []
    for k in range(1, count + 1):
        integ.stepTo(duration * k / count)
        pos = context.getState(getPositions=True).getPositions(asNumpy=True)
        out.append(np.asarray(pos.value_in_unit(openmm.unit.nanometer)))
    return out


def contact_shapes(n, count=3, seed=1):
    """T(2,3) templates on a thin tube (minor radius 0.26 d: strands about 0.52 d apart, inside
    the steric range 0.561 d), jittered by 0.02 d: shapes where the steric force acts."""
    rng = np.random.default_rng(seed)
    x = torus_knot(2, 3, n, minor_radius=0.26)
    return [x + rng.normal(scale=0.02, size=x.shape) for _ in range(count)]


def _fd_error(system, y, h=1e-5, probes=12, seed=2):
    """Largest |F + dE/dx| over ``probes`` coordinates (central differences), relative."""
    rng = np.random.default_rng(seed)
    f, _ = _forces(system, y)
    worst = 0.0
    for flat in rng.choice(y.size, probes, replace=False):
        i, k = divmod(int(flat), 3)
        yp, ym = y.copy(), y.copy()
        yp[i, k] += h
        ym[i, k] -= h
        fd = -(_forces(system, yp)[1] - _forces(system, ym)[1]) / (2 * h)
        worst = max(worst, abs(fd - f[i, k]) / np.max(np.abs(f)))
    return worst


def check_forces(names, x, model, duration):
    """Force and energy differences against ``current`` on Reference (largest, relative), at
    shapes along the run and at shapes with steric contacts; and each variant's forces
    against central differences of its own energy at one contact shape."""
    shapes = shapes_along_run(x, model, duration) + contact_shapes(len(x))
    out = {}
    for name in names:
        if name.partition("@")[0].endswith(("nosteric", "noforce")):
            continue
        worst_f = worst_e = 0.0
        for y in shapes:
            y = y - y.mean(axis=0)
            f0, e0 = _forces(chain_system(y, model), y)
            f1, e1 = _forces(_variant(name)[0](y, model), y)
            worst_f = max(worst_f, float(np.max(np.abs(f1 - f0)) / np.max(np.abs(f0))))
            worst_e = max(worst_e, abs(e1 - e0) / abs(e0))
        y = shapes[-1] - shapes[-1].mean(axis=0)
        out[name] = (worst_f, worst_e, _fd_error(_variant(name)[0](y, model), y))
    return out


def check_bits(names, x, model, duration):
    """Largest position difference (d) after ``duration`` against ``current`` (CPU variants)
    or ``reference`` (Reference variants), from ``x``; and the evaluations of both."""
    def final(name):
        with Pinned(_variant(name)[3]):
            context, integ = _context(name, x, model)
            integ.stepTo(duration)
            pos = context.getState(getPositions=True).getPositions(asNumpy=True)
            return np.asarray(pos.value_in_unit(openmm.unit.nanometer)), \
                integ.getNumForceEvaluations()
    base = {"CPU": final("current"), "Reference": final("reference")}
    out = {}
    for name in names:
        if name.partition("@")[0].endswith(("nosteric", "noforce")):
            continue
        pos, ev = final(name)
        ref_pos, ref_ev = base[_variant(name)[1]]
        out[name] = (float(np.max(np.abs(pos - ref_pos))), ev, ref_ev)
    return out
