"""The knot-type checks of a run: the periodic watch and the template's deferred check.

Both send chains to the knot worker (:mod:`knotmm.knots.worker`) and judge its answers at
later reports, so a run never waits for topoly. :func:`knot_watch` makes a run's
:class:`knotmm.engine.reporters.KnotTypeWatch`; :class:`TemplateKnotCheck` judges the
template of :func:`knotmm.shapes.builder.build_template` (``identify="later"``);
:func:`finish_checks` decides, at the end of a run, what is still waited for;
:func:`record_checks` writes the outcome into run.toml's facts.

The watches' record is kept in every checkpoint and a resumed run continues it from there
(:mod:`knotmm.engine.check_record`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

from knotmm.engine.check_record import KeptIdentifier, json_safe, restore_knot_watch
from knotmm.engine.interrupt import raise_if_requested
from knotmm.engine.schedule import TimeScheduled
from knotmm.errors import ConfigError
from knotmm.knots.identify import worker_ready

__all__ = [
    "FINISH_PATIENCE_S",
    "ChainsIdentifier",
    "LinkingWatch",
    "TemplateKnotCheck",
    "TopologyChecks",
    "checks_not_made",
    "check_stop_on_change",
    "finish_checks",
    "knot_watch",
    "linking_watch",
    "record_linking",
    "record_checks",
]

log = logging.getLogger(__name__)

#: The note of a run whose knot-type checks are skipped for want of topoly (said once).
NO_TOPOLY_NOTE = ("note: knot type not checked (neither the template's nor along the run): "
                  "topoly is not installed, and strands can pass one another in the model, so "
                  "the knot type may change unseen; pip install 'knotmm[knots]' checks it (or set "
                  "run.topology_check_interval = 0 to run unchecked)")
_no_topoly_said = False


@dataclass(frozen=True)
class TopologyChecks:
    """How a run watches its topology (a part of the run plan, :mod:`knotmm.plan`).

    Attributes
    ----------
    interval : float
        ``run.topology_check_interval``, in tau_d (0: no checks).
    on_change : {"warn", "stop"}
        ``run.on_topology_change``.
    """

    interval: float
    on_change: str

    @classmethod
    def of(cls, cfg) -> TopologyChecks:
        """The checks of a run configuration."""
        return cls(float(cfg["run.topology_check_interval"]), str(cfg["run.on_topology_change"]))


class TemplateKnotCheck(TimeScheduled):
    """Judges a new run's template knot type once the knot worker has answered.

    :func:`knotmm.shapes.builder.build_template` (``identify="later"``) sent the template to
    the worker, so the run does not wait for topoly's start-up. At each frame this reporter
    looks (without waiting) whether the answer is back; then run.toml's ``template`` facts
    are updated, or :class:`knotmm.errors.TemplateError` stops the run if the template is
    not the knot asked for. An answer not back when the run ends leaves
    ``template_knot_type`` unset, with a note.
    """

    def __init__(self, template, facts: dict, interval: float, recorded: dict | None = None):
        super().__init__(interval)
        self.template = template
        self.facts = facts
        #: What the judged check wrote into ``facts`` (kept in the checkpoints: a resumed run
        #: whose run.toml was written before the answer came restores it from there).
        self.recorded: dict | None = recorded

    def report(self, simulation, state) -> None:
        self.advance()
        self.settle(wait=False)

    def settle(self, wait: bool, end: bool = False) -> None:
        """Judge the answer if it is back (``wait``: wait for it); ``end``: the run ends."""
        template = self.template
        if template is None or not template.knot_type_pending:
            return
        template.settle_knot_type(wait)
        if not template.knot_type_pending:
            recorded = dict(template.facts)
            if template.notes:
                recorded["notes"] = list(template.notes)
            self.recorded = json_safe(recorded)
            self.facts.update(recorded)
        elif end:
            self.facts["notes"] = [*template.notes, "template knot type not checked: the run "
                                   "ended before topoly had started in the knot worker"]


def check_stop_on_change(checks: TopologyChecks) -> None:
    """A run asked to stop at a change of knot type must be able to see one."""
    from knotmm.knots.identify import topoly_available

    if checks.on_change == "stop" and checks.interval > 0 and not topoly_available():
        raise ConfigError(
            'run.on_topology_change = "stop" needs knot-type checks, and topoly is not '
            "installed: pip install 'knotmm[knots]', or set run.on_topology_change = \"warn\" "
            "(or run.topology_check_interval = 0) to run unchecked"
        )


def knot_watch(sim, checks: TopologyChecks, facts, counters, record=None, positions=None):
    """The knot-type reporter of a run, or None (checks off, or no topoly).

    Parameters
    ----------
    sim : Simulation
    checks : TopologyChecks
    facts : dict
        run.toml's ``[knotmm]`` facts (``knot_type_watch`` is noted there).
    counters : dict
        The checkpoint's counters (``checks``: the index of the next check).
    record : dict or None
        A resumed run's record of its checks
        (:func:`knotmm.engine.check_record.resumed_record`); None: a new run.
    positions : ndarray or None
        The record's positions of the checks under way, shape (k, n_beads, 3).
    """
    from knotmm.engine.reporters import KnotTypeWatch
    from knotmm.knots.identify import topoly_available
    from knotmm.knots.worker import IsolatedKnotIdentifier

    if not checks.interval > 0:
        return None
    if not topoly_available():  # the core install: said once, at normal verbosity
        global _no_topoly_said
        if any(sim.layout.closed):
            facts["knot_type_watch"] = "not made: topoly is not installed"
            if not _no_topoly_said:
                _no_topoly_said = True
                log.warning(NO_TOPOLY_NOTE)
        return None
    identify = IsolatedKnotIdentifier(chiral=True)
    if not sim.layout.is_single_ring:  # several chains: the type of each ring, in order
        if not any(sim.layout.closed):
            facts["knot_type_watch"] = "not made: an open chain has no knot type"
            return None
        identify = ChainsIdentifier(identify, sim.layout)
        facts["knot_type_watch"] = ("the knot type of each closed chain, in chain order "
                                    "(\"+3_1, -3_1\"): a change of any one is a change")
    identify = KeptIdentifier(identify)
    identify.start()  # off the run's path: the worker imports topoly meanwhile
    watch = KnotTypeWatch(
        checks.interval,
        on_change=checks.on_change,
        first_index=max(1, counters.get("checks", 0)),
        identify=identify,
    )
    state = (record or {}).get("knot")
    if state is not None:
        restore_knot_watch(watch, state, positions)
    else:  # identified in the worker beside the run, not before it
        watch.identify_start(sim.positions)
    return watch


def record_checks(facts: dict, watch) -> None:
    """run.toml's record of the knot-type checks so far (the watch holds the whole run's,
    a resumed run's included): ``knot_type_start``, ``knot_type``, ``knot_type_checks``,
    ``knot_type_checks_dropped`` and every change in order (``knot_type_changes``)."""
    if watch.start_type is not None:
        facts["knot_type_start"] = watch.start_type
    facts["knot_type"] = watch.current
    # only checks that ran: not those whose worker failed (watch.skipped) or were dropped
    facts["knot_type_checks"] = watch.checks
    if watch.dropped:
        facts["knot_type_checks_dropped"] = watch.dropped
    else:
        facts.pop("knot_type_checks_dropped", None)
    facts["knot_type_changes"] = [{"time": t, "from": str(a), "to": str(b)}
                                  for t, a, b in watch.changes]


#: At the end of a run with checks still under way, how long to wait for the knot worker to
#: finish starting (topoly's import: about 2 s) before recording them as not made, in s.
FINISH_PATIENCE_S = 5.0


def _under_way(judge: TemplateKnotCheck, watch) -> bool:
    """Whether a check still waits for the knot worker (the template's or the watch's)."""
    template = judge.template
    if template is not None and template.knot_type_pending:
        return True
    # the watch's queue of identifications submitted and not judged yet
    return watch is not None and bool(getattr(watch, "_pending", None)
                                      or getattr(watch, "_start", None) is not None)


def finish_checks(judge: TemplateKnotCheck, watch, wait: bool = False,
                  patience: float = FINISH_PATIENCE_S) -> None:
    """At the end of a run, judge the checks still under way beside it.

    Parameters
    ----------
    judge : TemplateKnotCheck
    watch : KnotTypeWatch or None
    wait : bool
        Wait for every answer even while the worker is still starting (a sweep, which
        identifies knot types in its analysis next anyway).
    patience : float
        Otherwise, seconds to wait for a worker still starting (topoly's import, about 2 s):
        once it is up every answer is waited for (an identification takes a fraction of a
        second); if it is not up by then, what is left is recorded as not made
        (``knot_type_checks_dropped``, a note for the template), and ``knotmm run`` says so
        on its summary line (:func:`checks_not_made`).
    """
    if not wait and _under_way(judge, watch):
        deadline = time.monotonic() + patience
        while not worker_ready() and time.monotonic() < deadline:
            raise_if_requested()  # Ctrl-C while waiting: the run stops here, resumable
            time.sleep(0.05)
    judge.settle(wait=wait or worker_ready(), end=True)
    if watch is not None:
        watch.finish(wait=wait)


def checks_not_made(facts: dict) -> tuple[int, bool]:
    """From run.toml's ``[knotmm]`` facts: the knot-type checks a run recorded as not made,
    and whether the template's knot type was left unchecked."""
    dropped = int(facts.get("knot_type_checks_dropped", 0) or 0)
    template = facts.get("template_knot_type") is None and any(
        "template knot type not checked" in str(n) for n in facts.get("notes", []) or [])
    return dropped, template


class LinkingWatch(TimeScheduled):
    """Check the linking number of every pair of closed chains every ``interval`` tau_d
    (the Gauss integral, :func:`knotmm.knots.linking.linking_numbers`; no topoly needed).

    Two rings can pass through each other as one strand can pass through another
    (docs/model.md): a change is recorded as ``(time, "A-B", old, new)`` in :attr:`changes`
    and logged, or stops the run (:class:`knotmm.errors.KnotTypeChanged`) with
    ``on_change="stop"``. A frame in which two chains touch (the integral is no integer)
    is not a check (:attr:`skipped`).

    Parameters
    ----------
    interval : float
        In tau_d.
    layout : ChainLayout
    current : dict or None
        ``{"A-B": Lk}`` to compare the first check with (the numbers at the checkpoint, on
        resume); None: the first check sets it.
    on_change : {"warn", "stop"}
    first_index : int

    Attributes
    ----------
    start : dict or None
        The numbers at the start of the run (run.toml's ``linking_numbers``).
    """

    def __init__(self, interval, layout, current=None, on_change="warn", first_index=0):
        super().__init__(interval, first_index)
        self.rings = [(cid, sl) for cid, sl, ring in
                      zip(layout.ids, layout.slices(), layout.closed, strict=True) if ring]
        self.start: dict | None = None
        self.current = dict(current) if current else None
        self.on_change = on_change
        self.changes: list[tuple[float, str, int, int]] = []
        self.checks = 0
        self.skipped = 0

    def numbers(self, positions) -> dict[str, int] | None:
        """``{"A-B": Lk}`` of the closed chains in ``positions``; None if two touch."""
        from knotmm.knots.linking import linking_numbers

        try:
            found = linking_numbers([positions[sl] for _, sl in self.rings])
        except ValueError:
            return None
        ids = [cid for cid, _ in self.rings]
        return {f"{ids[i]}-{ids[j]}": int(v) for (i, j), v in found.items()}

    def report(self, simulation, state) -> None:
        from knotmm.errors import KnotTypeChanged

        self.advance()
        found = self.numbers(simulation.positions)
        if found is None:
            self.skipped += 1
            return
        self.checks += 1
        if self.current is None:
            self.current = found
            return
        changed = [(pair, self.current.get(pair), lk) for pair, lk in found.items()
                   if self.current.get(pair) != lk]
        self.current = found
        if not changed:
            return
        when = simulation.time
        for pair, old, new in changed:
            self.changes.append((when, pair, old, new))
        message = "; ".join(f"the linking number of chains {pair} changed from {old} to {new}"
                            for pair, old, new in changed)
        message += f" by t = {when:.6g} tau_d (step {simulation.currentStep}): rings passed " \
                   "through each other"
        if self.on_change == "stop":
            raise KnotTypeChanged(message + '; run.on_topology_change = "stop"')
        import logging

        logging.getLogger(__name__).warning(message)


def linking_watch(sim, checks: TopologyChecks, facts, record=None) -> LinkingWatch | None:
    """The linking-number reporter of a run with two or more closed chains, or None.

    ``record``: a resumed run's record of its checks
    (:func:`knotmm.engine.check_record.resumed_record`), whose ``linking`` table the watch
    continues; None: a new run, whose start numbers go into ``facts`` (``linking_numbers``).
    """
    interval = checks.interval
    if interval <= 0 or sum(sim.layout.closed) < 2:
        return None
    state = (record or {}).get("linking")
    index = int(sim.time / interval + 1e-9) + 1
    if state is not None and state.get("index") is not None and state.get("interval") == interval:
        index = int(state["index"])  # a check due at the checkpoint's time is made there
    watch = LinkingWatch(interval, sim.layout, on_change=checks.on_change,
                         first_index=index)
    if state is None:
        watch.start = watch.numbers(sim.positions) or {}
        watch.current = dict(watch.start) or None
    else:
        watch.start = dict(state.get("start") or {})
        watch.current = dict(state["current"]) if state.get("current") else None
        watch.changes = [(float(t), pair, a, b) for t, pair, a, b in state.get("changes", [])]
        watch.checks = int(state.get("checks", 0))
        watch.skipped = int(state.get("skipped", 0))
    facts["linking_numbers"] = dict(watch.start)
    return watch


def record_linking(facts: dict, watch: LinkingWatch) -> None:
    """run.toml's record of the linking checks so far (the watch holds the whole run's):
    ``linking_numbers``, ``linking_checks``, ``linking_numbers_now`` and every change in
    order (``linking_number_changes``)."""
    facts["linking_numbers"] = dict(watch.start or {})
    facts["linking_checks"] = watch.checks
    if watch.current is not None:
        facts["linking_numbers_now"] = dict(watch.current)
    facts["linking_number_changes"] = [
        {"time": t, "chains": pair, "from": int(a) if a is not None else None, "to": int(b)}
        for t, pair, a, b in watch.changes]


class ChainsIdentifier:
    """The knot identifier of a system: each closed chain identified on its own (in the one
    knot worker), the names joined in chain order (``"+3_1, -3_1"``).

    Wraps an identifier with ``submit``/``ready``/``start``/``close``
    (:class:`knotmm.knots.worker.IsolatedKnotIdentifier`); a chain the worker cannot name
    makes the joined answer None (not identified) or ``"unknown"``.
    """

    def __init__(self, identify, layout):
        self._identify = identify
        self._rings = [sl for sl, ring in zip(layout.slices(), layout.closed, strict=True)
                       if ring]

    def start(self) -> None:
        self._identify.start()

    @property
    def ready(self) -> bool:
        return bool(getattr(self._identify, "ready", True))

    def submit(self, positions):
        return _JoinedHandle([self._identify.submit(positions[sl]) for sl in self._rings])

    def __call__(self, positions):
        return self.submit(positions).result()

    def close(self) -> None:
        closer = getattr(self._identify, "close", None)
        if closer is not None:
            closer()


class _JoinedHandle:
    """The identifications of several chains as one: done when all are."""

    def __init__(self, handles):
        self._handles = handles

    def done(self) -> bool:
        return all(h.done() for h in self._handles)

    def result(self) -> str | None:
        names = [h.result() for h in self._handles]
        if any(n is None for n in names):
            return None
        if any(n == "unknown" for n in names):
            return "unknown"
        return ", ".join(names)
