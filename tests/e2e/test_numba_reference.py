"""benchmarks/numba_chain.py (the yardstick of issue 12's speed targets) is knotmm's model.

The hand-written numba program and knotmm's Python engine (OpenMM forces, Reference platform,
double precision) must give the same velocity field and the same Heun trajectory; otherwise
the benchmark ratios would compare different models.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from knotmm.dynamics.deterministic import Heun
from knotmm.engine.simulation import Simulation
from knotmm.model.parameters import ChainModel
from knotmm.shapes import torus_knot

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "numba_chain.py"


@pytest.fixture(scope="module")
def numba_chain():
    if "numba_chain" not in sys.modules:
        spec = importlib.util.spec_from_file_location("numba_chain", _PATH)
        module = importlib.util.module_from_spec(spec)
        sys.modules["numba_chain"] = module  # numba's cache looks the module up by name
        spec.loader.exec_module(module)
    return sys.modules["numba_chain"]


def _velocity(module, x, **params):
    f = np.empty_like(x)
    v = np.empty_like(x)
    module.velocity(x, module.parameters(**params), f, v)
    return v


@pytest.mark.parametrize(
    "scale, params",
    [
        (1.0, {}),  # the template: bonds, bending, gravity; RPY both branches
        (0.45, {}),  # shrunk: i, i+2 pairs inside the steric range (0.56 d)
        (1.0, {"bending_stiffness": 5000.0}),
    ],
    ids=["template", "steric", "stiff"],
)
def test_velocity_equals_python_engine(numba_chain, scale, params):
    x = torus_knot(2, 3, 90) * scale
    sim = Simulation(x, ChainModel(**params), Heun(0.02), platform="Reference")
    expected = sim.velocity(x)
    got = _velocity(numba_chain, x, **params)
    rel = np.max(np.abs(got - expected)) / np.max(np.abs(expected))
    assert rel < 1e-6
    if scale < 1:  # the steric term is really active here
        no_lj = _velocity(numba_chain, x, lj_epsilon=0.0)
        assert np.max(np.abs(no_lj - expected)) / np.max(np.abs(expected)) > 1e-2


def test_heun_trajectory_equals_python_engine(numba_chain):
    """5 tau_d of Heun at dt = 0.02 from the N = 90 template: equal to 1e-10 d.

    Both are double precision with the same formulas; measured difference 1.4e-14 d (only
    the order of floating-point sums differs).
    """
    x = torus_knot(2, 3, 90)
    sim = Simulation(x, integrator=Heun(0.02), platform="Reference")
    sim.run(5.0)
    assert sim.currentStep == 250
    y = numba_chain.heun(x, numba_chain.parameters(), 0.02, 250)
    assert np.max(np.abs(y - sim.positions)) < 1e-10
    assert np.max(np.abs(y - x)) > 1.0  # it did move (about 5 d down)


def test_read_start_pdb_is_in_angstrom(numba_chain, tmp_path):
    """A PDB (Angstrom, 3 decimals) reads back as d; a .npy as is."""
    x = torus_knot(2, 3, 30)
    lines = [
        f"HETATM{i + 1:5d}  C   BEA A   1    {10 * a:8.3f}{10 * b:8.3f}{10 * c:8.3f}  1.00  0.00"
        for i, (a, b, c) in enumerate(x)
    ]
    (tmp_path / "t.pdb").write_text("\n".join(lines + ["END"]) + "\n")
    np.save(tmp_path / "t.npy", x)
    assert np.max(np.abs(numba_chain.read_start(str(tmp_path / "t.pdb")) - x)) < 1e-4 + 1e-12
    assert np.array_equal(numba_chain.read_start(str(tmp_path / "t.npy")), x)
