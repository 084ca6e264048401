"""The record of a run's knot-type and linking-number checks, kept in its checkpoints.

run.toml is written at the start and at the end of a run, so after a kill it says nothing of
the checks made since the start. Every checkpoint therefore holds, beside the state, the
record of the checks at that state (:func:`checks_record`, in the counters under
:data:`RECORD_KEY`): the knot-type watch's start type, current type, changes and counts, and
its identifications still under way with the positions they were made of
(:func:`checks_positions`, the checkpoint array :data:`POSITIONS_ARRAY`); the linking watch's
start and current numbers, changes, counts and next check; the template's judged facts. A
resumed run continues from there (:func:`resumed_record`), so its record is the one the run
would have had without the interruption. A checkpoint from before that record falls back to
run.toml's (:func:`record_from_facts`), with a warning.
"""

from __future__ import annotations

import json
import logging
from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "POSITIONS_ARRAY",
    "RECORD_KEY",
    "KeptIdentifier",
    "ResumedChecks",
    "checks_positions",
    "checks_record",
    "json_safe",
    "record_from_facts",
    "restore_knot_watch",
    "resumed_record",
]

log = logging.getLogger(__name__)


#: The key of a run's checkpoint counters that holds the record of its checks
#: (:func:`checks_record`).
RECORD_KEY = "topology"
#: The checkpoint array (:mod:`knotmm.engine.checkpoint`, ``array_<name>``) of the positions
#: of the knot checks still under way, float64, shape (k, n_beads, 3), in d.
POSITIONS_ARRAY = "knot_check_positions"


def restore_knot_watch(watch, state: dict, positions) -> None:
    """Continue a :class:`knotmm.engine.reporters.KnotTypeWatch` from a checkpoint's record
    (``state``: :func:`checks_record`'s ``knot``): its types, changes and counts, and the
    identifications under way sent again with the ``positions`` they were made of (those
    whose positions are missing count as dropped)."""
    watch.start_type = state.get("start_type")
    watch.current = state.get("current")
    watch.changes = [(float(t), a, b) for t, a, b in state.get("changes", [])]
    watch.checks = int(state.get("checks", 0))
    watch.skipped = int(state.get("skipped", 0))
    watch.dropped = int(state.get("dropped", 0))
    count = 0 if positions is None else len(positions)
    submit = watch._identify.submit
    at = state.get("start_at")
    if at is not None and at < count:
        watch._start = submit(positions[at])
    for when, step, at in state.get("pending", []):
        if at < count:
            watch._pending.append((float(when), int(step), submit(positions[at])))
        else:
            watch.dropped += 1


def checks_record(watch, links, judge) -> dict:
    """The record of a run's checks, to keep in its checkpoint (JSON values).

    ``knot``: the knot-type watch's start type, current type, changes (``[time, from,
    to]``), counts and its identifications under way (``pending``: ``[time, step, at]``;
    ``start_at``: the start's), ``at`` indexing :func:`checks_positions`; ``linking``: the
    linking watch's start numbers, current numbers, changes (``[time, pair, from, to]``),
    counts and next check; ``template``: what the template's judged check recorded in
    run.toml (``facts``), or, while it is under way, ``pending`` and the SHA-256 of the
    template's positions (a resumed run builds it again and checks it). A table is left out
    when its check is off.
    """
    record: dict = {}
    if watch is not None:
        start_at = 0 if watch._start is not None else None
        first = 0 if start_at is None else 1  # at: the index in checks_positions
        pending = [[float(when), int(step), first + k]
                   for k, (when, step, _) in enumerate(watch._pending)]
        record["knot"] = {
            "start_type": watch.start_type,
            "current": watch.current,
            "changes": [[float(t), a, b] for t, a, b in watch.changes],
            "checks": watch.checks,
            "skipped": watch.skipped,
            "dropped": watch.dropped,
            "start_at": start_at,
            "pending": pending,
        }
    if links is not None:
        record["linking"] = {
            "start": links.start,
            "current": links.current,
            "changes": [[float(t), pair, a, b] for t, pair, a, b in links.changes],
            "checks": links.checks,
            "skipped": links.skipped,
            "index": links.index,
            "interval": links.interval,
        }
    template = judge.template
    if template is not None and template.knot_type_pending:  # its shape, to build it again
        record["template"] = {"pending": True, "sha256": _digest(template.positions)}
    elif judge.recorded is not None:
        record["template"] = {"facts": judge.recorded}
    return record


def checks_positions(watch) -> dict:
    """The checkpoint arrays of :func:`checks_record`: ``{POSITIONS_ARRAY: (k, n_beads, 3)}``
    for the knot identifications under way (the start's first), or ``{}`` when none is."""
    if watch is None:
        return {}
    handles = ([watch._start] if watch._start is not None else []) + [
        handle for _, _, handle in watch._pending]
    if not handles:
        return {}
    return {POSITIONS_ARRAY: np.stack([handle.positions for handle in handles])}


def record_from_facts(facts: dict) -> dict:
    """A record (:func:`checks_record`) made from run.toml's facts, for a checkpoint written
    before knotmm kept one there: what run.toml says at the stop (nothing after a SIGKILL)."""
    record: dict = {}
    if facts.get("knot_type") is not None:
        record["knot"] = {
            "start_type": facts.get("knot_type_start"),
            "current": facts["knot_type"],
            "changes": [[c.get("time"), c.get("from"), c.get("to")]
                        for c in facts.get("knot_type_changes", []) or []],
            "checks": int(facts.get("knot_type_checks", 0) or 0),
            "dropped": int(facts.get("knot_type_checks_dropped", 0) or 0),
        }
    start = facts.get("linking_numbers")
    if start is not None:
        record["linking"] = {
            "start": dict(start),
            "current": dict(facts.get("linking_numbers_now") or start) or None,
            "changes": [[c.get("time"), c.get("chains"), c.get("from"), c.get("to")]
                        for c in facts.get("linking_number_changes", []) or []],
            "checks": int(facts.get("linking_checks", 0) or 0),
        }
    return record


class ResumedChecks(NamedTuple):
    """What a resumed run's checks continue (:func:`resumed_record`): the ``record``
    (:func:`checks_record`'s or :func:`record_from_facts`'s), the ``positions`` of the knot
    checks under way (k, n_beads, 3), what the template's judged check ``recorded`` in
    run.toml, and the ``template`` built again when its check was under way; or None."""

    record: dict | None = None
    positions: np.ndarray | None = None
    recorded: dict | None = None
    template: Any = None


def resumed_record(state: dict, facts: dict, plan, path) -> ResumedChecks:
    """What a resumed run's checks continue, from its checkpoint ``state``
    (:func:`knotmm.engine.checkpoint.read_checkpoint`, of file ``path``).

    The template's judged facts are put back into run.toml's ``facts`` (a run killed before
    its end wrote them only into its checkpoints); a template whose check was still under
    way is built again from the run's plan (``plan``, :func:`knotmm.plan.resume_plan`'s:
    its configuration, template spec and memory budget) and judged in the resumed run. A
    checkpoint written before knotmm kept the record there gives :func:`record_from_facts`,
    with a warning.
    """
    record = state["counters"].get(RECORD_KEY)
    if record is None:
        if plan.checks.interval > 0:
            log.warning("%s holds no record of the knot-type and linking checks (an older "
                        "knotmm's): their record goes on from run.toml's, which misses what "
                        "happened after run.toml was last written (after a kill: all of it)",
                        path)
        record = record_from_facts(facts)
    entry = record.get("template") or {}
    recorded = entry.get("facts") or None
    template = _template_again(plan, entry, facts) if entry.get("pending") else None
    if recorded:
        facts.update(recorded)
    return ResumedChecks(record, (state.get("arrays") or {}).get(POSITIONS_ARRAY), recorded,
                         template)


def _template_again(plan, entry: dict, facts: dict):
    """The run's template built again, its knot check sent to the worker; None, with a
    warning and a note in ``facts``, when it cannot be (a template file changed since, ...)."""
    from knotmm.errors import KnotmmError
    from knotmm.shapes.builder import build_template

    try:
        template = build_template(plan.config, identify="later", spec=plan.template,
                                  resources=plan.resources)
        why = None if _digest(template.positions) == entry.get("sha256") else "another shape"
    except (KnotmmError, OSError) as exc:
        why = str(exc)
    if why is None:
        return template if template.knot_type_pending else None
    log.warning("the template's knot type was not checked before the stop, and the template "
                "cannot be built again to check it: %s", why)
    facts["notes"] = [*(facts.get("notes") or []), "template knot type not checked: the run "
                      "was stopped before the knot worker had answered"]
    return None


def _digest(positions) -> str:
    """The SHA-256 of float64 positions (a template's shape, to recognise it)."""
    import hashlib

    return hashlib.sha256(np.ascontiguousarray(positions, dtype=np.float64).tobytes()).hexdigest()


def json_safe(value):
    """``value`` with numpy scalars and arrays made plain Python (for a checkpoint's JSON)."""
    return json.loads(json.dumps(value, default=lambda v: v.tolist()))


class KeptIdentifier:
    """An identifier whose handles keep the positions they were sent (float64 copies), so
    that a checkpoint can hold the identifications still under way."""

    def __init__(self, identify):
        self._identify = identify

    def start(self) -> None:
        self._identify.start()

    @property
    def ready(self) -> bool:
        return bool(getattr(self._identify, "ready", True))

    def submit(self, positions):
        kept = np.array(positions, dtype=np.float64)
        return KeptHandle(self._identify.submit(kept), kept)

    def close(self) -> None:
        closer = getattr(self._identify, "close", None)
        if closer is not None:
            closer()


class KeptHandle:
    """A handle of :class:`KeptIdentifier`: the identifier's handle and its positions."""

    def __init__(self, handle, positions):
        self._handle = handle
        self.positions = positions

    def done(self) -> bool:
        return self._handle.done()

    def result(self):
        return self._handle.result()
