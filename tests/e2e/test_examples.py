"""Every run and sweep file under examples/ is valid, and its template can be built."""

from pathlib import Path

import pytest

from knotmm.config import load_run_file, read_toml
from knotmm.dynamics.registry import integrator_from_config
from knotmm.shapes import build_template
from knotmm.sweep import load_sweep_file

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*/*.toml"))


def test_examples_are_found():
    assert len(EXAMPLES) >= 10


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_example_file_is_valid(path):
    if "sweep" in read_toml(path):
        configs = [point.config for point in load_sweep_file(path).points]
    else:
        configs = [load_run_file(path)]
    assert configs
    for cfg in configs:
        integrator_from_config(cfg)  # the integrator fits run.peclet
        assert build_template(cfg).positions.shape[1] == 3
