"""The knot-type checks of a run: the periodic watch and the template's deferred check.

Both send chains to the knot worker (:mod:`knotmm.knots.worker`) and judge its answers at
later reports, so a run never waits for topoly. :func:`knot_watch` makes a run's
:class:`knotmm.engine.reporters.KnotTypeWatch`; :class:`TemplateKnotCheck` judges the
template of :func:`knotmm.shapes.builder.build_template` (``identify="later"``);
:func:`finish_checks` decides, at the end of a run, what is still waited for;
:func:`record_checks` writes the outcome into run.toml's facts.
"""

from __future__ import annotations

from knotmm.engine.schedule import TimeScheduled
from knotmm.errors import ConfigError
from knotmm.knots.identify import worker_ready

__all__ = [
    "TemplateKnotCheck",
    "check_stop_on_change",
    "finish_checks",
    "knot_watch",
    "record_checks",
]


class TemplateKnotCheck(TimeScheduled):
    """Judges a new run's template knot type once the knot worker has answered.

    :func:`knotmm.shapes.builder.build_template` (``identify="later"``) sent the template to
    the worker, so the run does not wait for topoly's start-up. At each frame this reporter
    looks (without waiting) whether the answer is back; then run.toml's ``template`` facts
    are updated, or :class:`knotmm.errors.TemplateError` stops the run if the template is
    not the knot asked for. An answer not back when the run ends leaves
    ``template_knot_type`` unset, with a note.
    """

    def __init__(self, template, facts: dict, interval: float):
        super().__init__(interval)
        self.template = template
        self.facts = facts

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
            self.facts.update(template.facts)
            if template.notes:
                self.facts["notes"] = list(template.notes)
        elif end:
            self.facts["notes"] = [*template.notes, "template knot type not checked: the run "
                                   "ended before topoly had started in the knot worker"]


def check_stop_on_change(cfg) -> None:
    """A run asked to stop at a change of knot type must be able to see one."""
    from knotmm.knots.identify import topoly_available

    if (cfg["run.on_topology_change"] == "stop" and cfg["run.topology_check_interval"] > 0
            and not topoly_available()):
        raise ConfigError(
            'run.on_topology_change = "stop" needs knot-type checks, and topoly is not '
            "installed: pip install 'knotmm[knots]', or set run.on_topology_change = \"warn\" "
            "(or run.topology_check_interval = 0) to run unchecked"
        )


def knot_watch(sim, cfg, facts, counters, resuming):
    """The knot-type reporter of a run, or None (checks off, or no topoly)."""
    from knotmm.engine.reporters import KnotTypeWatch
    from knotmm.knots.identify import topoly_available

    if not (cfg["run.topology_check_interval"] > 0 and topoly_available()):
        return None
    expected = facts.get("knot_type") if resuming else None
    watch = KnotTypeWatch(
        cfg["run.topology_check_interval"],
        expected=expected,
        on_change=cfg["run.on_topology_change"],
        first_index=max(1, counters.get("checks", 0)),
    )
    if expected is None:  # identified in the worker beside the run, not before it
        watch.identify_start(sim.positions)
    return watch


def record_checks(facts: dict, watch) -> None:
    if watch.start_type is not None:
        facts["knot_type_start"] = watch.start_type
    facts["knot_type"] = watch.current
    # only checks that ran: not those whose worker failed (watch.skipped) or were dropped
    facts["knot_type_checks"] = int(facts.get("knot_type_checks", 0)) + watch.checks
    if watch.dropped:
        facts["knot_type_checks_dropped"] = (
            int(facts.get("knot_type_checks_dropped", 0)) + watch.dropped
        )
    changes = list(facts.get("knot_type_changes", []))
    changes += [{"time": t, "from": str(a), "to": str(b)} for t, a, b in watch.changes]
    facts["knot_type_changes"] = changes


def finish_checks(judge: TemplateKnotCheck, watch, wait: bool = False) -> None:
    """At the end of a run, judge the checks still under way beside it.

    Parameters
    ----------
    judge : TemplateKnotCheck
    watch : KnotTypeWatch or None
    wait : bool
        Wait for every answer even while the worker is still starting (a sweep, which
        identifies knot types in its analysis next anyway). Otherwise answers are waited for
        only once the worker is up: a short run does not wait for topoly's import; what is
        left is recorded as not checked.
    """
    judge.settle(wait=wait or worker_ready(), end=True)
    if watch is not None:
        watch.finish(wait=wait)
