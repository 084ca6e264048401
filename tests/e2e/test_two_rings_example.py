"""examples/two_rings: the README's section 1 digits against a fresh computation.

The rigid-body solve of the script (two rigid coaxial rings in the RPY mobility) must give
equal speeds and the README's digits; the stiffest pair (k = 5000, A = 5000) at D0 = 3, run
again for the first 5 tau_d as the script runs it, must start at the README's speed and
closing rate. A change of the engine, the template or the model that moves them makes this
fail; the example is then rerun and its README updated.
"""

from __future__ import annotations

import re
from pathlib import Path

from example_scripts import load_script

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "two_rings"


def _script():
    return load_script(EXAMPLE / "run_two_rings.py")


def test_two_rings_rigid_limit_and_stiff_start_are_the_readmes(tmp_path):
    rings = _script()
    readme = (EXAMPLE / "README.md").read_text()
    row = re.search(r"\| 3 \| ([\d.]+), ([\d.]+) \(difference 0\) \| ([\d.]+) \| ([-\d.e]+) \|",
                    readme)
    assert row, "section 1's D0 = 3 row"
    lower, upper = rings.rigid_ring_speeds(3.0)
    assert abs(upper - lower) < 1e-12
    assert f"{lower:.6f}" == row.group(1) and f"{upper:.6f}" == row.group(2)
    a, k = rings.CASES["k5000_A5000"]
    directory = rings.run_case("stiff", rings.settings(a, 3.0, k), tmp_path, 5.0, 0.5)
    m = rings.measure(directory)
    assert f"{m['speed_first_5']:.4f}" == row.group(3)
    assert f"{m['dz_rate_first_5']:.2e}" == f"{float(row.group(4)):.2e}"
