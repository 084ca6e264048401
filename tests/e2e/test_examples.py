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
    built = set()
    for cfg in configs:
        integrator_from_config(cfg)  # the integrator fits run.peclet
        data = cfg.to_dict()
        shape = repr((data.get("knot"), data.get("chains"), data.get("model")))
        # one template per distinct shape: a sweep's replicas differ only by run.seed (the
        # seed of their perturbation), which `knotmm sweep --dry-run` checks point by point
        if shape not in built:
            built.add(shape)
            assert build_template(cfg).positions.shape[1] == 3
