"""The start a run asks for, as typed values: :class:`TemplateSpec`.

The geometry code reads a run file's ``[knot]`` (or ``[[chains]]``) and ``[model]`` keys,
never its ``[run]`` table: what the template takes from there (the perturbation's seed, the
longest bond a run accepts) comes in a :class:`TemplateSpec`, and the memory budget in a
:class:`knotmm.shapes.resources.RunResources`. The run plan (:func:`knotmm.plan.prepare`)
makes both once; :meth:`TemplateSpec.of` and :meth:`RunResources.of
<knotmm.shapes.resources.RunResources.of>` are the two places of ``shapes/`` that read
``run.*`` keys (``tests/shapes/test_no_run_keys.py`` holds it), for the plan and for a
caller without one (:func:`knotmm.shapes.builder.build_system`, ``knotmm template``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

__all__ = ["TemplateSpec"]


@dataclass(frozen=True)
class TemplateSpec:
    """The start a run asks for: its ``[knot]`` table or ``[[chains]]`` entries, resolved.

    Attributes
    ----------
    kind : str
        ``knot.kind`` (the first chain's for ``[[chains]]``).
    chains : tuple of Mapping
        The chains' keys as the run file gives them, one read-only table each (one for a
        ``[knot]`` run).
    perturbation : float
        ``knot.perturbation``, in d (the largest of the chains').
    seeds : tuple of int or None
        Per chain, the seed of its perturbation (``knot.seed``, else ``run.seed``, plus the
        chain's index for ``[[chains]]`` entries without their own seed); None where a chain
        is not perturbed.
    max_bond_length : float
        ``run.max_bond_length``, in d: a start with a longer bond is refused (the run would
        stop at its first step).
    """

    kind: str
    chains: tuple[Mapping[str, Any], ...]
    perturbation: float
    seeds: tuple[int | None, ...]
    max_bond_length: float

    @classmethod
    def of(cls, cfg) -> TemplateSpec:
        """The spec of a run configuration (its ``[knot]`` or ``[[chains]]`` keys, with
        ``run.seed`` and ``run.max_bond_length``)."""
        entries = cfg.chains
        several = entries is not None
        if not several:
            entries = [cfg.table("knot")]
        seed = int(cfg["run.seed"])
        seeds = []
        for c, entry in enumerate(entries):
            if not float(entry.get("perturbation") or 0.0) > 0.0:
                seeds.append(None)
            elif entry.get("seed") is not None:
                seeds.append(int(entry["seed"]))
            else:
                seeds.append(seed + (c if several else 0))
        return cls(
            kind=str(entries[0]["kind"]),
            chains=tuple(MappingProxyType(dict(e)) for e in entries),
            perturbation=max(float(e.get("perturbation") or 0.0) for e in entries),
            seeds=tuple(seeds),
            max_bond_length=float(cfg["run.max_bond_length"]),
        )

    @property
    def seed(self) -> int | None:
        """The first chain's perturbation seed (a ``[knot]`` run's)."""
        return self.seeds[0]

    def part(self, index: int) -> TemplateSpec:
        """The spec of ``[[chains]]`` entry ``index`` alone."""
        entry = self.chains[index]
        return replace(self, kind=str(entry["kind"]), chains=(entry,),
                       perturbation=float(entry.get("perturbation") or 0.0),
                       seeds=(self.seeds[index],))

    def unperturbed(self) -> TemplateSpec:
        """The same start without its perturbation (an open filament's closed shape)."""
        return replace(self, perturbation=0.0, seeds=(None,) * len(self.seeds))
