"""The Python examples of ``plugin/README.md`` run as written, one after the other, as a reader
pasting them into one session would (they failed before: ``stepTo(50)`` came after
``step(1000)`` had passed t = 50, and the frame loop stepped back to t = 0.5)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import mdtraj
import pytest

import knotmm.plugin

README = Path(__file__).resolve().parents[2] / "plugin" / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


@pytest.mark.skipif(not knotmm.plugin.available(), reason=str(knotmm.plugin.load_error()))
def test_the_plugin_readme_examples_run_as_written(tmp_path):
    blocks = _python_blocks()
    assert len(blocks) >= 2
    check = ("t = sim.context.getState().getTime()._value\n"
             "assert start >= 50.0 and abs(t - (start + 200.0)) < 1e-9, (start, t)\n")
    script = tmp_path / "example.py"
    script.write_text("\n".join(blocks) + "\n" + check)
    # the CPU platform, whatever device platform the plugin also has here (pocl is slow)
    env = dict(os.environ, OPENMM_DEFAULT_PLATFORM="CPU")
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    frames = mdtraj.load(str(tmp_path / "frames.dcd"), top=str(_topology(tmp_path)))
    assert frames.n_frames == 400
    assert (tmp_path / "traj.dcd").stat().st_size > 0


def _topology(tmp_path: Path) -> Path:
    """A PDB of the examples' 90-bead chain, for mdtraj to read the DCD with."""
    import openmm.app as app

    from knotmm.model.topology import bead_topology
    from knotmm.shapes import torus_knot

    path = tmp_path / "top.pdb"
    with path.open("w") as fh:
        app.PDBFile.writeFile(bead_topology(90), torus_knot(2, 3, 90), fh)
    return path
