"""What a run of a template needs beyond the template: memory.

:func:`check_memory` refuses, before anything is written, a run whose largest allocation
cannot fit in the memory available, with one line giving the estimate. Only the dense
Brownian noise (``run.noise = "cholesky"``, ``docs/model.md``, "Dynamics") grows faster than
the chain; everything else a run holds grows in proportion to the number of beads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from knotmm.dynamics.registry import REGISTRY, resolve
from knotmm.errors import ConfigError

__all__ = ["RunResources", "available_memory", "check_memory"]


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


@dataclass(frozen=True)
class RunResources:
    """What a run's memory depends on beyond the template, as plain values.

    The geometry code receives this, not the run file's ``[run]`` table: the run plan
    (:func:`knotmm.plan.prepare`) makes it from ``run.integrator``, ``run.peclet`` and
    ``run.noise`` once (:meth:`of`), and :func:`knotmm.shapes.builder.build_template`
    checks the chain it builds against it (:func:`check_memory`) before the knot check.

    Attributes
    ----------
    brownian : bool
        Whether the run draws Brownian noise (a Brownian integrator at a finite Pe).
    noise : {"auto", "cholesky", "lanczos"}
        ``run.noise`` as asked; :meth:`noise_method` resolves it for a chain's size.
    """

    brownian: bool = False
    noise: str = "auto"

    @classmethod
    def of(cls, cfg) -> RunResources:
        """The resources of a run configuration: with :meth:`knotmm.shapes.spec.TemplateSpec.of`,
        one of the two places of ``shapes/`` that read ``run.*`` keys."""
        name, _ = resolve(cfg["run.integrator"], cfg["run.peclet"], cfg["run.timestep"])
        brownian = REGISTRY[name].brownian and math.isfinite(float(cfg["run.peclet"]))
        return cls(brownian=bool(brownian), noise=str(cfg["run.noise"]))

    def noise_method(self, n_beads: int) -> str | None:
        """``"cholesky"`` or ``"lanczos"`` for a chain of ``n_beads``; None without noise."""
        if not self.brownian:
            return None
        from knotmm.dynamics.noise import NoiseGenerator  # numba and scipy: Brownian runs only

        return NoiseGenerator(self.noise).method_for(n_beads)

    def need(self, n_beads: int) -> tuple[int, str]:
        """The largest allocation a run of ``n_beads`` needs, in bytes, and what it is.

        Only the dense Brownian noise grows faster than the chain: ``run.noise = "cholesky"``
        builds the 3N x 3N RPY mobility and its Cholesky factor, ``2 (3N)^2`` float64 (both
        engines: the plugin's LAPACK factor is the same size). The deterministic dynamics,
        the Lanczos noise, the forces and the files take memory in proportion to N.
        """
        if self.noise_method(n_beads) == "cholesky":
            size = 3 * n_beads
            what = f"the dense {size} x {size} RPY mobility and its Cholesky factor"
            return 2 * size * size * 8, what
        return 0, ""

    def check(self, n_beads: int) -> None:
        """Refuse, in one line with the estimate, a run whose dense noise cannot fit in
        memory (:func:`available_memory`)."""
        need, what = self.need(n_beads)
        have = available_memory()
        if need == 0 or have is None or need <= have:
            return
        raise ConfigError(
            f"knot.beads={n_beads} with run.noise = {self.noise!r} needs about "
            f"{need / 1e9:.3g} GB for {what}, more than the {have / 1e9:.3g} GB available; "
            'use run.noise = "lanczos" (matrix-free) or fewer beads'
        )


def check_memory(resources: RunResources, n_beads: int) -> None:
    """Refuse, in one line naming ``run.noise`` and ``knot.beads``, a run of ``n_beads``
    whose dense noise cannot fit in memory (:meth:`RunResources.check`)."""
    resources.check(n_beads)
