"""A checked starting shape (:class:`Template`) and its knot check still under way.

:func:`knotmm.shapes.builder.build_template` makes a :class:`Template`; with
``identify="later"`` its knot type is judged by :meth:`Template.settle_knot_type` once the
knot worker has answered. Units: d.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from knotmm.model.layout import ChainLayout
from knotmm.shapes.checks import TemplateCheck, judge_knot_type

__all__ = ["PendingKnotCheck", "Template"]

logger = logging.getLogger("knotmm.shapes.builder")


@dataclass
class Template:
    """A checked starting shape.

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), float64, in d
        Bead positions, centre of mass at the origin.
    description : str
        E.g. ``"T(2,3), +3_1"`` (the knot type signed with its handedness).
    resolved : dict
        Dotted run-file keys -> values the run should record (``{"knot.major_radius": 4.2}``).
    writhe : float
        Writhe of the closed chain (> 0: right-handed).
    knot_type : str or None
        Knot type found by topoly, signed with its handedness (``"+3_1"``,
        :mod:`knotmm.knots.chirality`), ``None`` if not checked.
    notes : list of str
        Remarks for the user and the run's record.
    check : TemplateCheck or None
        The full check report.
    pending : PendingKnotCheck or None
        The knot identification still under way (``build_template(identify="later")``).
    layout : ChainLayout or None
        The chains of a system of several chains or of an open one (``None``: one ring).
    parts : list of Template
        A system's chains, each its own checked template at its place, in the order of
        ``layout`` (empty for one chain); ``positions`` holds them one after another.
    chain_facts : dict
        What run.toml records of a system beyond its chains' facts (linking numbers).
    source : dict
        Where a start read from a file came from (``knot.kind = "file"``: the file, the
        frame, its time in the run that wrote it; :func:`knotmm.shapes.file_start.file_source`),
        recorded as ``started_from``; empty for other starts.
    """

    positions: np.ndarray
    description: str
    resolved: dict[str, Any]
    writhe: float
    knot_type: str | None
    notes: list[str] = field(default_factory=list)
    check: TemplateCheck | None = None
    pending: PendingKnotCheck | None = field(default=None, repr=False, compare=False)
    layout: ChainLayout | None = None
    parts: list[Template] = field(default_factory=list, repr=False)
    chain_facts: dict[str, Any] = field(default_factory=dict)
    source: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        if self.layout is None:
            self.layout = ChainLayout.ring(int(self.positions.shape[0]))

    @property
    def n_beads(self) -> int:
        return int(self.positions.shape[0])

    @property
    def knot_type_pending(self) -> bool:
        """Whether the knot identification of ``build_template(identify="later")`` is out."""
        return self.pending is not None or any(p.knot_type_pending for p in self.parts)

    def settle_knot_type(self, wait: bool = False) -> list[str]:
        """Judge a deferred knot identification once it is back.

        Parameters
        ----------
        wait : bool
            Wait for the answer (else return at once when it is not back yet).

        Returns
        -------
        list of str
            The notes it added (also appended to :attr:`notes`); empty when nothing was
            judged. :attr:`knot_type`, :attr:`description` and :attr:`check` are updated.

        Raises
        ------
        TemplateError
            If the template is not the knot it should be (the message
            :func:`build_template` gives with ``identify="now"``).
        """
        if self.parts:
            before = [part.description for part in self.parts]
            added = [note for part in self.parts for note in part.settle_knot_type(wait)]
            self.notes.extend(added)
            self.knot_type = _joined(p.knot_type for p in self.parts)
            self._describe_parts(before)
            return added
        pending = self.pending
        if pending is None or not (wait or pending.handle.done()):
            return []
        self.pending = None
        before = len(self.check.notes)
        judge_knot_type(pending.handle.result(), pending.expected, self.check)
        self.knot_type, self.description, found = pending.conclude(self.check)
        added = found[before:]
        self.notes.extend(added)
        for note in added:
            logger.info("template: %s", note)
        return added

    def _describe_parts(self, before: list[str]) -> None:
        """Put the chains' settled descriptions (their knot types, found after the start)
        into the system's ("2 chains: A T(2,3), +3_1; B component 0, 0_1"), which names
        chain ``c`` as ``"{id} {description}"`` after ``": "`` or ``"; "``."""
        text = self.description
        for cid, old, part in zip(self.layout.ids, before, self.parts, strict=True):
            if part.description == old:
                continue
            for sep in (": ", "; "):
                here = f"{sep}{cid} {old}"
                at = text.find(here)
                ends = at + len(here)
                if at >= 0 and (ends == len(text) or text.startswith(";", ends)):
                    text = f"{text[:at]}{sep}{cid} {part.description}{text[ends:]}"
                    break
        self.description = text

    @property
    def facts(self) -> dict[str, Any]:
        """What run.toml's ``[knotmm]`` table records about the start.

        ``template`` (the description), ``template_writhe``, ``template_knot_type`` and
        ``template_bond_range`` (``[shortest, longest]`` bond of the start, in d: off the
        bond length for a file or an explicit ``knot.major_radius``; the bonds relax in the
        run). A system of several chains records ``template`` and ``chains``, one table per
        chain (``id``, ``beads``, ``closed`` and that chain's facts), and ``chain_facts``. A
        start read from a file records ``started_from`` (:attr:`source`).
        """
        source = {"started_from": dict(self.source)} if self.source else {}
        if self.parts:
            chains = []
            layout = self.layout
            for cid, part, ring in zip(layout.ids, self.parts, layout.closed, strict=True):
                entry = {"id": cid, "beads": part.n_beads, "closed": ring}
                entry.update({k: v for k, v in part.facts.items() if v is not None})
                chains.append(entry)
            return {"template": self.description, "chains": chains, **self.chain_facts,
                    **source}
        facts: dict[str, Any] = {
            "template": self.description,
            "template_writhe": float(self.writhe),
            "template_knot_type": self.knot_type,
        }
        if self.check is not None:
            facts["template_bond_range"] = [float(self.check.bond_min), float(self.check.bond_max)]
        facts.update(source)
        return facts


def _joined(types) -> str | None:
    """The chains' knot types in one string ("+3_1, 0_1"); None when none is known."""
    types = list(types)
    return None if all(t is None for t in types) else ", ".join(str(t) for t in types)


@dataclass
class PendingKnotCheck:
    """A template's knot identification under way in the worker."""

    handle: Any
    expected: str | None
    conclude: Callable[[TemplateCheck], tuple[str | None, str, list[str]]]
