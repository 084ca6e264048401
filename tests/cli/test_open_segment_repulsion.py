"""``knotmm run`` of an open filament with ``model.segment_repulsion = true`` (issue 31).

It stopped with an OpenMMException traceback and exit code 1: the Context was given the
sites of one ring (as many as beads) where an open chain has one bond fewer.
"""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.io.dcd import read_dcd
from knotmm.plugin import available as plugin_available

RUN_FILE = """
[knot]
kind = "straight"
beads = 10

[model]
segment_repulsion = true

[run]
duration = 0.5
engine = "{engine}"

[output]
frame_interval = 0.25
"""


@pytest.mark.parametrize("engine", [
    "python",
    pytest.param("plugin", marks=pytest.mark.skipif(not plugin_available(),
                                                    reason="plugin not built")),
])
def test_open_filament_with_segment_repulsion_runs(engine, tmp_path, capsys):
    run_file = tmp_path / "open.toml"
    run_file.write_text(RUN_FILE.format(engine=engine))
    out = tmp_path / "run"
    code = main(["run", str(run_file), "--out", str(out), "--no-progress"])
    _, err = capsys.readouterr()
    assert code == 0, err
    frames, notes = read_dcd(out / "trajectory.dcd")
    assert frames.shape == (3, 10, 3) and not notes
    assert np.all(np.isfinite(frames))
