"""Checkpoints written by an earlier build of the plugin still resume, and resume the same run.

``data/checkpoints_v3.npz`` holds Context checkpoints (``Context.createCheckpoint``) written by
the plugin before its stepper was split out of the Reference kernel (knotmm 0.1, integrator
layout 1, stepper layout 3), at t = 0.5 tau_d of a 30-bead T(2,3) ring, with the positions,
counters, step size and time that the old build reached from there after ``stepTo(1.0)`` and
``step(3)``. ``data/checkpoints_v4.npz`` holds the same for stepper layout 4 (written by the
build before backend v2, which added the state in double as layout 5; generated on the
development machine with the earlier build): rk23 and leimkuhler_matthews on Reference,
ito_heun_adaptive with Lanczos noise and segment sites on CPU (one thread), rk23 and
ito_heun_adaptive in mixed precision on OpenCL (skipped where the plugin has no OpenCL
kernel). ``data/checkpoints_v5.npz`` holds the same for stepper layout 5 (the state in double,
before the counter-based noise of layout 6; written by that build with the cases above and
euler_maruyama on Reference and on OpenCL in double precision): a Brownian run resumed from
it continues with the sequential noise stream it was drawing from. A layout-4 checkpoint has no
state: the next step starts from the Context's positions and keeps the cached velocity and
held kick while they are those they were computed at. The layout is read field by field, so a
field read out of place would load a wrong cached velocity, step-size memory, noise stream or
held kick, and the run would go elsewhere.

A Context checkpoint also holds OpenMM's own state, which only the OpenMM version that wrote it
reads: the test is skipped under another version. On the same machine the trajectories were
compared bit for bit when the stepper was split out; here, where the machine may differ (the
RPY pair loop has per-CPU code paths), the double-precision Reference platform is held to
1e-10 d and the single-precision CPU and mixed-precision OpenCL platforms to 1e-4 d (on
OpenCL the state is now kept in double where the old build read it back rounded at each
step, and the Lanczos Krylov loop moved to the device: the runs part by rounding).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import openmm
import openmm.version
import pytest

import knotmm.plugin as kp
from knotmm.engine.engines import plugin_platforms
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system, site_positions
from knotmm.shapes.geometry import torus_knot

DATA = Path(__file__).parent / "data"
#: Stepper layout -> the file of checkpoints written by a build that wrote that layout.
FILES = {3: DATA / "checkpoints_v3.npz", 4: DATA / "checkpoints_v4.npz",
         5: DATA / "checkpoints_v5.npz"}
_data = {layout: np.load(path, allow_pickle=layout < 5) for layout, path in FILES.items()}


def _params():
    for layout, data in _data.items():
        n = len([k for k in data.files if k.endswith("_method")])
        for case in range(n):
            platform = str(data[f"case{case}_platform"])
            skip = []
            if str(data["openmm_version"]) != openmm.version.version:
                skip.append(pytest.mark.skip(
                    reason=f"the checkpoints were written by OpenMM {data['openmm_version']}"))
            elif platform not in plugin_platforms():
                skip.append(pytest.mark.skip(reason=f"the plugin has no kernel on {platform} here"))
            yield pytest.param(layout, case, marks=skip, id=f"v{layout}-{case}-{platform}")


@pytest.mark.parametrize(("layout", "case"), list(_params()))
def test_old_checkpoint_resumes_the_same_run(layout, case):
    data = _data[layout]
    get = lambda key: data[f"case{case}_{key}"]  # noqa: E731
    method, kT, noise = str(get("method")), float(get("kT")), str(get("noise"))
    segments, platform = bool(get("segments")), str(get("platform"))
    precision = str(get("precision")) if f"case{case}_precision" in data.files else ""
    kp.use_lapack_cholesky()
    x = torus_knot(2, 3, 30)
    model = ChainModel(segment_repulsion=segments)
    integ = kp.RPYIntegrator(0.002 if kT > 0 else 0.01, method, 1e-4, kT=kT, seed=7, noise=noise)
    props = ({"Precision": precision} if precision
             else {"Threads": "1"} if platform == "CPU" and layout >= 4 else {})
    ctx = openmm.Context(chain_system(x, model), integ, openmm.Platform.getPlatformByName(platform),
                         props)
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
    # (an adaptive run's last step size follows its error estimates: on OpenCL these now come
    # from the device's Lanczos, rounded otherwise than the old build's host loop: 2e-9 ps)
    assert state.getTime().value_in_unit(openmm.unit.picosecond) == pytest.approx(
        float(get("time")), abs=1e-12 if not precision else 1e-8)
