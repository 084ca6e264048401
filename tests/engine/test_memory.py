"""A long deterministic run keeps its memory flat (nothing accumulates per step or frame)."""

import gc
import resource
import tracemalloc

from knotmm.config import RunConfig
from knotmm.workflow import run


def test_memory_stays_flat_over_a_long_run(tmp_path):
    def go(duration, name):
        cfg = RunConfig.from_dict({
            "knot": {"beads": 40},
            "run": {"duration": duration, "topology_check_interval": 0.0},
            "output": {"frame_interval": 0.25},
        })
        run(cfg, directory=tmp_path / name, progress=False)
        gc.collect()

    go(5.0, "warm")  # compiles and caches everything once
    tracemalloc.start()
    go(5.0, "short")
    short_peak = tracemalloc.get_traced_memory()[1]
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    tracemalloc.reset_peak()
    go(80.0, "long")  # 16x the steps and frames
    long_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    # Python-side peak must not scale with the run's length
    assert long_peak < 1.5 * short_peak + 2_000_000, (short_peak, long_peak)
    # resident set (C++ included, in KiB on Linux): at most 50 MB more
    assert rss_after - rss_before < 50_000, (rss_before, rss_after)
