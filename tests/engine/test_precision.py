"""``run.precision``: a device platform's precision, asked for and recorded; refused where it
cannot be had."""

from __future__ import annotations

import subprocess
import sys

import pytest

from knotmm.config import RunConfig
from knotmm.engine import engines
from knotmm.engine.engines import select_platform
from knotmm.errors import ConfigError


def test_double_on_the_cpu_platform_is_refused_in_one_line():
    with pytest.raises(ConfigError, match='run.precision = "double".*Reference'):
        select_platform("CPU", 30, precision="double")


@pytest.mark.parametrize("precision", ["auto", "double"])
def test_the_reference_platform_takes_auto_and_double(precision):
    platform, properties = select_platform("Reference", 30, precision=precision)
    assert platform.getName() == "Reference" and "Precision" not in properties


@pytest.mark.skipif("OpenCL" not in engines.platform_names(), reason="no OpenCL platform")
@pytest.mark.parametrize(("precision", "expected"), [("auto", "mixed"), ("double", "double")])
def test_a_device_platform_gets_the_precision_asked_for(precision, expected):
    assert select_platform("OpenCL", 30, precision=precision)[1]["Precision"] == expected


def test_an_unknown_precision_is_a_config_error():
    with pytest.raises(ConfigError, match="run.precision"):
        RunConfig.from_dict({"run": {"precision": "single"}})


def test_knotmm_run_refuses_double_on_the_cpu_with_exit_code_2(tmp_path):
    (tmp_path / "run.toml").write_text(
        '[knot]\nbeads = 30\n[run]\nduration = 1\nplatform = "CPU"\nprecision = "double"\n'
        '[output]\ndirectory = "out"\n')
    proc = subprocess.run([sys.executable, "-m", "knotmm", "run", "run.toml", "--no-progress"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "run.precision" in proc.stderr
    assert not (tmp_path / "out").exists()
