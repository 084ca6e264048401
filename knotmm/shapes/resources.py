"""What a run of a template needs beyond the template: memory.

:func:`check_memory` refuses, before anything is written, a run whose largest allocation
cannot fit in the memory available, with one line giving the estimate. Only the dense
Brownian noise (``run.noise = "cholesky"``, ``docs/model.md``, "Dynamics") grows faster than
the chain; everything else a run holds grows in proportion to the number of beads.
"""

from __future__ import annotations

import math

from knotmm.dynamics.registry import REGISTRY, resolve
from knotmm.errors import ConfigError

__all__ = ["available_memory", "check_memory", "run_memory"]


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def run_memory(cfg, n_beads: int) -> tuple[int, str]:
    """The largest allocation a run of ``n_beads`` needs, in bytes, and what it is.

    Only the dense Brownian noise grows faster than the chain: ``run.noise = "cholesky"``
    builds the 3N x 3N RPY mobility and its Cholesky factor, ``2 (3N)^2`` float64. The
    deterministic dynamics, the Lanczos noise, the forces and the files take memory in
    proportion to N.
    """
    name, _ = resolve(cfg["run.integrator"], cfg["run.peclet"], cfg["run.timestep"])
    brownian = REGISTRY[name].brownian and math.isfinite(float(cfg["run.peclet"]))
    if not brownian:
        return 0, ""
    from knotmm.dynamics.noise import NoiseGenerator  # numba and scipy: Brownian runs only

    if NoiseGenerator(cfg["run.noise"]).method_for(n_beads) == "cholesky":
        size = 3 * n_beads
        what = f"the dense {size} x {size} RPY mobility and its Cholesky factor"
        return 2 * size * size * 8, what
    return 0, ""


def check_memory(cfg, n_beads: int) -> None:
    """Refuse, in one line with the estimate, a run whose dense noise cannot fit in memory."""
    need, what = run_memory(cfg, n_beads)
    have = available_memory()
    if need == 0 or have is None or need <= have:
        return
    raise ConfigError(
        f"knot.beads={n_beads} with run.noise = {cfg['run.noise']!r} needs about "
        f"{need / 1e9:.3g} GB for {what}, more than the {have / 1e9:.3g} GB available; "
        'use run.noise = "lanczos" (matrix-free) or fewer beads'
    )
