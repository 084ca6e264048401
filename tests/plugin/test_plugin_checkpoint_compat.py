"""Checkpoints written by an earlier build of the plugin still resume, and resume the same run.

``data/checkpoints_v3.npz`` holds Context checkpoints (``Context.createCheckpoint``) written by
the plugin before its stepper was split out of the Reference kernel (knotmm 0.1, integrator
layout 1, stepper layout 3), at t = 0.5 tau_d of a 30-bead T(2,3) ring, with the positions,
counters, step size and time that the old build reached from there after ``stepTo(1.0)`` and
``step(3)``. The layout is read field by field, so a field read out of place would load a wrong
cached velocity, step-size memory, noise stream or held kick, and the run would go elsewhere.

A Context checkpoint also holds OpenMM's own state, which only the OpenMM version that wrote it
reads: the test is skipped under another version. On the same machine the trajectories were
compared bit for bit when the stepper was split out; here, where the machine may differ (the
RPY pair loop has per-CPU code paths), the double-precision Reference platform is held to
1e-10 d and the single-precision CPU platform to 1e-4 d.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import openmm
import openmm.version
import pytest

import knotmm.plugin as kp
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system, site_positions
from knotmm.shapes.geometry import torus_knot

DATA = Path(__file__).parent / "data" / "checkpoints_v3.npz"


def _cases():
    data = np.load(DATA)
    n = len([k for k in data.files if k.endswith("_method")])
    return data, n


_data, _n = _cases()
pytestmark = pytest.mark.skipif(
    str(_data["openmm_version"]) != openmm.version.version,
    reason=f"the checkpoints were written by OpenMM {_data['openmm_version']}",
)


@pytest.mark.parametrize("case", range(_n))
def test_old_checkpoint_resumes_the_same_run(case):
    get = lambda key: _data[f"case{case}_{key}"]  # noqa: E731
    method, kT, noise = str(get("method")), float(get("kT")), str(get("noise"))
    segments, platform = bool(get("segments")), str(get("platform"))
    kp.use_lapack_cholesky()
    x = torus_knot(2, 3, 30)
    model = ChainModel(segment_repulsion=segments)
    integ = kp.RPYIntegrator(0.002 if kT > 0 else 0.01, method, 1e-4, kT=kT, seed=7, noise=noise)
    ctx = openmm.Context(chain_system(x, model), integ, openmm.Platform.getPlatformByName(platform))
    ctx.setPositions(site_positions(x, model, ChainLayout.ring(30)))
    ctx.loadCheckpoint(get("checkpoint").tobytes())
    assert ctx.getState().getTime().value_in_unit(openmm.unit.picosecond) == pytest.approx(0.5)
    integ.stepTo(1.0)
    integ.step(3)
    state = ctx.getState(getPositions=True)
    got = state.getPositions(asNumpy=True).value_in_unit(openmm.unit.nanometer)
    moved = np.abs(got - get("positions")).max()
    tolerance = 1e-10 if platform == "Reference" else 1e-4
    assert moved <= tolerance, f"{method} on {platform}: {moved:.3g} d from the old build's run"
    counts = (integ.getNumAcceptedSteps(), integ.getNumForceEvaluations(),
              integ.getNumRejectedSteps())
    assert counts == tuple(int(c) for c in get("counts"))
    assert state.getTime().value_in_unit(openmm.unit.picosecond) == pytest.approx(
        float(get("time")), abs=1e-12)
