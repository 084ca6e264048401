"""knotmm.limits: the largest sizes a run may ask for, held in the run-file schema before
anything is allocated (issue 30, BUG-16 and BUG-18)."""

from __future__ import annotations

import pytest

from knotmm import limits
from knotmm.config import RunConfig
from knotmm.errors import ConfigError


@pytest.mark.parametrize(("data", "says"), [
    ({"knot": {"kind": "braid", "word": [2**63 - 1, 1], "beads": 60}},
     r"knot.word = \[9223372036854775807, 1\]: generator 9223372036854775807 asks for"),
    ({"knot": {"kind": "braid", "word": [1, -60], "beads": 60}}, "use generators below 60"),
    ({"knot": {"p": 10**30, "q": 3}}, "knot.p = 1000000000000000000000000000000"),
    ({"chains": [{"kind": "braid", "word": [1, 99], "beads": 40}]}, r"chains\[0\]\.word"),
    ({"run": {"replicas": 10**9}}, "run.replicas = 1000000000: must be <= 10000"),
    ({"knot": {"beads": 10**5}}, "knot.beads = 100000: must be <= 99999"),
    ({"chains": [{"beads": 50_000}, {"beads": 50_000, "offset": [9.0, 0.0, 0.0]}]},
     "chains: 100000 beads in all"),
    ({"run": {"threads": 129}}, "run.threads = 129: must be <= 128"),
    ({"run": {"duration": 3e9}, "output": {"frame_interval": 1.0}}, "2147483647 frames"),
    ({"run": {"duration": 10**400}}, r"run.duration = 1000.*\(401 characters\): expected a "
                                     "finite number"),
    ({"chains": [{"beads": 30, "offset": [10**400, 0, 0]}]}, r"chains\[0\]\.offset"),
    ({"chains": [{"beads": 30, "offset": [1.0e5 + 1, 0, 0]}]}, r"within \+-100000"),
], ids=["braid_2_63", "braid_equal_beads", "torus_p", "chains_braid", "replicas", "beads",
        "chains_total", "threads", "frames", "duration_int", "offset_int", "offset"])
def test_sizes_past_the_limits_are_refused_in_one_line(data, says):
    with pytest.raises(ConfigError, match=says) as info:
        RunConfig.from_dict(data)
    assert "\n" not in str(info.value) and len(str(info.value)) < 500


def test_sizes_at_the_limits_are_accepted():
    cfg = RunConfig.from_dict({
        "knot": {"kind": "braid", "word": [1, -59], "beads": 60},
        "run": {"replicas": limits.MAX_REPLICAS, "threads": limits.MAX_THREADS,
                "peclet": limits.MIN_PECLET},
        "model": {"gravity": limits.MAX_GRAVITY},
    })
    assert cfg["run.replicas"] == 10_000
    assert RunConfig.from_dict({"knot": {"beads": limits.MAX_BEADS}})["knot.beads"] == 99_999
    chains = RunConfig.from_dict({"chains": [{"beads": 30, "offset": [-1e5, 0, 1e5]}]}).chains
    assert chains[0]["offset"] == [-1e5, 0.0, 1e5]


def test_shown_cuts_long_values():
    assert limits.shown(12) == "12"
    text = limits.shown(10**400)
    assert text.startswith("1000") and "(401 characters)" in text and len(text) < 70


@pytest.mark.parametrize(("run", "key"), [
    ({"min_timestep": 1e-320, "max_timestep": 1e-300}, "run.max_timestep"),
    ({"integrator": "heun", "timestep": 1e-300}, "run.timestep"),
])
def test_a_run_that_needs_more_than_2_63_steps_is_refused(run, key):
    """A run whose largest step cannot reach run.duration within OpenMM's 64-bit step count
    never finishes (the audit's max_timestep = 1e-300 ran for 11 minutes): refused, naming the
    key; 2 tau_d at 1e-300 is 2e300 steps, far past 2^63 = 9.2e18."""
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        RunConfig.from_dict({"knot": {"beads": 30}, "run": {"duration": 2.0, **run}})


def test_a_tiny_first_step_of_an_adaptive_method_is_not_refused():
    """rk23's run.timestep is only its first step (the audit's timestep = 1e-320 held)."""
    cfg = RunConfig.from_dict({"knot": {"beads": 30},
                               "run": {"duration": 2.0, "timestep": 1e-320}})
    assert cfg["run.timestep"] == 1e-320


@pytest.mark.parametrize(("data", "reason"), [
    ({"knot": {"beads": 3}}, "5 digits"),
    ({"model": {"lj_sigma": -1.0}}, "float32"),
    ({"run": {"replicas": 0}}, "32-bit"),
])
def test_a_value_below_a_natural_lower_bound_gets_no_upper_limits_reason(data, reason):
    """The limit's reason is told with the limit (beads = 3 was refused "must be >= 4
    (topology.pdb numbers its atoms with 5 digits)"); Pe's limit is its lower bound."""
    with pytest.raises(ConfigError) as info:
        RunConfig.from_dict(data)
    assert reason not in str(info.value), str(info.value)
    with pytest.raises(ConfigError, match="diffuses"):
        RunConfig.from_dict({"run": {"peclet": 1e-12}})
