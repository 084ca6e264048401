"""What a run of a template needs beyond the template: memory.

:func:`check_memory` refuses, before anything is written, a run whose largest allocation
cannot fit in the memory available, with one line giving the estimate. Only the dense
Brownian noise (``run.noise = "cholesky"``, ``docs/model.md``, "Dynamics") grows faster than
the chain; everything else a run holds grows in proportion to the number of beads. Where the
arrays live depends on the engine and the platform (:meth:`RunResources.need`): the dense
matrices are always on the host, the plugin's state on a device platform's device.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from knotmm.dynamics.registry import REGISTRY, resolve
from knotmm.errors import ConfigError

__all__ = ["DENSE_MATRICES", "DEVICE_VECTORS", "MemoryNeed", "RunResources",
           "available_memory", "check_memory"]


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


#: Dense 3N x 3N float64 matrices a Cholesky-noise run holds on the host, by engine: the
#: Python engine's RPY matrix and scipy's factor of it (``knotmm.dynamics.noise.
#: mobility_cholesky``); the plugin's lower triangle, factored in place (its Reference
#: backend's and, on a device platform, the host copy ``CommonRPYBackend`` factors:
#: ``RPYMobility::lowerMatrix`` then ``choleskyLower``). An engine not yet known counts
#: as the larger.
DENSE_MATRICES = {"python": 2, "plugin": 1}
#: Vectors of 3N float64 the plugin keeps on a device platform (``CommonRPYBackend``: its
#: ``forces``, ``noiseAt``, ``lanczosIn``, ``lanczosOut``, ``energyPosition``, 5; the
#: stepper's, made once for every method: ``StepWork`` 5, ``FixedSteps`` 6, ``RK23`` 5,
#: ``RKC2`` 11, the adaptive Brownian one 8). The mobility there is a pair loop
#: (matrix-free): nothing grows faster than N on the device.
DEVICE_VECTORS = 40


@dataclass(frozen=True)
class MemoryNeed:
    """The largest allocations of a run, where they live (:meth:`RunResources.need`).

    Attributes
    ----------
    host : int
        Bytes of the host's memory beyond what grows in proportion to N: the dense
        Brownian noise's matrices (0 without them).
    device : int
        Bytes of a device platform's memory the plugin's state takes (0 on the CPU and
        Reference platforms, and for the Python engine, which keeps its state on the host).
    what : str
        What the host's bytes are ("" for none).
    """

    host: int
    device: int = 0
    what: str = ""


@dataclass(frozen=True)
class RunResources:
    """What a run's memory depends on beyond the template, as plain values.

    The geometry code receives this, not the run file's ``[run]`` table: the run plan
    (:func:`knotmm.plan.prepare`) makes it from ``run.integrator``, ``run.peclet``,
    ``run.noise`` and ``run.engine`` once (:meth:`of`), resolves the engine, and
    :func:`knotmm.shapes.builder.build_template` checks the chain it builds against it
    (:func:`check_memory`) before the knot check.

    Attributes
    ----------
    brownian : bool
        Whether the run draws Brownian noise (a Brownian integrator at a finite Pe).
    noise : {"auto", "cholesky", "lanczos"}
        ``run.noise`` as asked; :meth:`noise_method` resolves it for a chain's size.
    engine : {"python", "plugin", "auto"}
        The engine that holds the noise's matrices (:data:`DENSE_MATRICES`); ``"auto"``:
        not resolved yet (``run.engine`` as asked), counted as the larger.
    """

    brownian: bool = False
    noise: str = "auto"
    engine: str = "auto"

    @classmethod
    def of(cls, cfg) -> RunResources:
        """The resources of a run configuration: with :meth:`knotmm.shapes.spec.TemplateSpec.of`,
        one of the two places of ``shapes/`` that read ``run.*`` keys."""
        name, _ = resolve(cfg["run.integrator"], cfg["run.peclet"], cfg["run.timestep"])
        brownian = REGISTRY[name].brownian and math.isfinite(float(cfg["run.peclet"]))
        return cls(brownian=bool(brownian), noise=str(cfg["run.noise"]),
                   engine=str(cfg["run.engine"]))

    def noise_method(self, n_beads: int) -> str | None:
        """``"cholesky"`` or ``"lanczos"`` for a chain of ``n_beads``; None without noise."""
        if not self.brownian:
            return None
        from knotmm.dynamics.noise import NoiseGenerator  # numba and scipy: Brownian runs only

        return NoiseGenerator(self.noise).method_for(n_beads)

    def need(self, n_beads: int, device: bool = False) -> MemoryNeed:
        """The largest allocations a run of ``n_beads`` needs, where they live.

        Only the dense Brownian noise grows faster than the chain: ``run.noise =
        "cholesky"`` holds :data:`DENSE_MATRICES` 3N x 3N float64 matrices on the host
        (whatever the platform: a device platform's plugin factors the mobility on the
        host too). On a ``device`` platform the plugin keeps its state there,
        :data:`DEVICE_VECTORS` vectors of 3N float64. The deterministic dynamics, the
        Lanczos noise, the forces and the files take host memory in proportion to N
        (not counted).
        """
        size = 3 * n_beads
        on_device = DEVICE_VECTORS * size * 8 if device and self.engine == "plugin" else 0
        if self.noise_method(n_beads) != "cholesky":
            return MemoryNeed(0, on_device)
        matrices = DENSE_MATRICES.get(self.engine, max(DENSE_MATRICES.values()))
        what = (f"the dense {size} x {size} RPY mobility and its Cholesky factor"
                + (" (factored in place)" if matrices == 1 else ""))
        return MemoryNeed(matrices * size * size * 8, on_device, what)

    def check(self, n_beads: int) -> None:
        """Refuse, in one line with the estimate, a run whose dense noise cannot fit in the
        host's memory (:func:`available_memory`)."""
        need = self.need(n_beads)
        have = available_memory()
        if need.host == 0 or have is None or need.host <= have:
            return
        raise ConfigError(
            f"knot.beads={n_beads} with run.noise = {self.noise!r} needs about "
            f"{need.host / 1e9:.3g} GB for {need.what}, more than the {have / 1e9:.3g} GB "
            'available; use run.noise = "lanczos" (matrix-free) or fewer beads'
        )


def check_memory(resources: RunResources, n_beads: int) -> None:
    """Refuse, in one line naming ``run.noise`` and ``knot.beads``, a run of ``n_beads``
    whose dense noise cannot fit in memory (:meth:`RunResources.check`)."""
    resources.check(n_beads)
