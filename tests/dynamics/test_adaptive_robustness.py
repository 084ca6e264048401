"""The defaults never blow up at finite temperature (issue 20's robustness grid; slow).

With ``run.integrator = "auto"`` (``ito_heun_adaptive`` at finite Pe) every run of T(2,3) at
N = 40, 90, 240 x Pe = 0.3, 0.5, 1, 2, 5, 20, 100 x segment repulsion off and on x seeds
1-3 must reach 50 tau_d with gravity on (the plugin engine, as ``knotmm run``). A blow-up
ends a run with a :class:`knotmm.errors.SimulationFault` (a bond beyond the engine's limit);
here every saved frame's bonds are also measured independently (mdtraj on the DCD) and must
stay below 2 d, against a rest length of 0.6 d. Strand passages (repulsion off) are allowed:
they are recorded, as in any run.

Each case takes 5-60 s at N = 40 and 90 and 1-15 min at N = 240 on one core; the whole grid
is hours. ``benchmarks/README.md`` holds the table of steps taken and rejected.
``-k "40-"`` and the like pick a part.
"""

from __future__ import annotations

import mdtraj
import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.io.rundir import read_facts
from knotmm.workflow import run

DURATION = 50.0
GRID = [
    pytest.param(n, pe, rep, seed, id=f"{n}-{pe:g}-{'rep' if rep else 'norep'}-{seed}")
    for n in (40, 90, 240)
    for pe in (0.3, 0.5, 1.0, 2.0, 5.0, 20.0, 100.0)
    for rep in (False, True)
    for seed in (1, 2, 3)
]


@pytest.mark.slow
@pytest.mark.parametrize(("beads", "peclet", "repulsion", "seed"), GRID)
def test_defaults_survive_finite_temperature_slow(tmp_path, beads, peclet, repulsion, seed):
    cfg = RunConfig.from_dict({
        "knot": {"beads": beads},
        "model": {"segment_repulsion": repulsion},
        "run": {"duration": DURATION, "peclet": peclet, "seed": seed},
        "output": {"frame_interval": 1.0},
    })
    result = run(cfg, directory=tmp_path / "run", progress=False)
    assert result.time == pytest.approx(DURATION)
    facts = read_facts(tmp_path / "run")
    assert facts["status"] == "finished"
    assert "ito_heun_adaptive" in facts["integrator_choice"]
    traj = mdtraj.load(str(tmp_path / "run" / "trajectory.dcd"),
                       top=str(tmp_path / "run" / "topology.pdb"))
    xyz = traj.xyz  # nm, which is d (the files hold 1 d = 10 Angstrom)
    bonds = np.linalg.norm(np.roll(xyz, -1, axis=1) - xyz, axis=2)
    assert traj.n_frames == int(DURATION) + 1
    assert bonds.max() < 2.0, f"bond of {bonds.max():.3g} d in frame {bonds.max(1).argmax()}"
