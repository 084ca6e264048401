"""A sweep's ``seeds = K`` replicas of a point, run as one replicated run.

Where a replicated run (``[run] replicas = K``, :mod:`knotmm.replicas`) would step its
replicas together (:func:`knotmm.engine.copies.copies_refusal`: the plugin engine on a platform
that holds copies, systems small enough, ``run.replica_stepping`` not
``"one_after_another"``), the replicas of one sweep point that are to be run or resumed are
handed to a worker as one task (:func:`knotmm.sweep.point.run_group`): they are stepped as the
copies of one OpenMM Context, each still a run of its own in its own point directory, with
its own seed, checkpoints, result row and failure. A point whose replicas cannot be stepped
together keeps one task per replica.

So that a small sweep still keeps every local worker busy, a point's replicas are split into
as many groups (of two or more) as it takes to give each worker one; each group is a
replicated run of its own.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

from knotmm.config import RunConfig

__all__ = ["group_tasks", "point_results", "stepping_refusal"]

log = logging.getLogger(__name__)


def stepping_refusal(cfg: RunConfig, count: int) -> str | None:
    """Why ``count`` replicas of ``cfg`` are not stepped together, or None if they are
    (the run plan's engine, platform and beads: :func:`knotmm.plan.prepare`, the check a
    replicated run makes); a configuration that cannot be planned is not grouped (each of
    its replicas then fails, or runs, as a point of its own)."""
    from knotmm.engine.copies import copies_refusal
    from knotmm.plan import prepare

    if count < 2 or cfg["run.replica_stepping"] == "one_after_another":
        return copies_refusal("plugin", "CPU", count, cfg["run.replica_stepping"])
    try:
        sim = prepare(cfg, identify="skip").simulation
    except Exception as exc:  # noqa: BLE001 - the replicas' own runs report it
        return f"the point cannot be planned ({type(exc).__name__})"
    return copies_refusal(sim.engine, sim.platform_name, count, cfg["run.replica_stepping"],
                          sim.n_beads, math.isfinite(cfg["run.peclet"]))


def group_tasks(tasks: Sequence[Mapping[str, Any]], keys: Mapping[str, tuple],
                workers: int | None, idle: Sequence[Mapping[str, Any]] = ()
                ) -> list[dict[str, Any]]:
    """The tasks, the replicas of each point that can be stepped together as group tasks.

    Parameters
    ----------
    tasks : sequence of dict
        One per point to run, resume or analyse (:func:`knotmm.sweep.point.run_point`).
    keys : dict
        Task name -> the key of its point without its seed; tasks that share a key are
        replicas of one point.
    workers : int or None
        Local worker processes the tasks are shared out to (None: a Dask cluster or this
        process: a point's replicas stay one group).
    idle : sequence of dict
        The finished replicas (``action = "skip"``): where a point's other replicas are run
        or resumed together, they are copies that stay put, so that a replica resumes as
        the copy it was (bit for bit) however few of its point's replicas are left to run.

    Returns
    -------
    list of dict
        Single tasks as they were (a replica whose point's replicas cannot be stepped
        together with ``"stepping"``: the reason), and group tasks ``{"name",
        "members"}`` (the members in replica order; a member ``"skip"`` is run and reported
        by nobody).
    """
    order = {name: i for i, name in enumerate(keys)}
    everyone: dict[tuple, list] = {}
    for task in [*tasks, *idle]:
        everyone.setdefault(keys[task["name"]], []).append(task)
    # in the sweep's order of points
    pending = dict.fromkeys(keys[t["name"]] for t in tasks if t.get("action") in ("run", "resume"))
    together = {}
    for key in pending:
        members = sorted(everyone[key], key=lambda t: order[t["name"]])
        first = next(t for t in members if t.get("action") in ("run", "resume"))
        why = stepping_refusal(RunConfig.from_dict(first["config"]), len(members))
        if why is None:
            together[key] = members
        else:
            log.info("the replicas of %s run one by one: %s", first["name"], why)
            for task in members:  # the reason goes into each replica's run.toml
                task["stepping"] = why
    if not together:
        return list(tasks)
    parts = 1
    if workers:  # one group for each worker at least, each of two replicas or more
        parts = max(1, math.ceil(workers / len(together)))
    grouped, placed = [], set()
    for members in together.values():
        fresh = all(t.get("action") == "run" for t in members)
        split = max(1, min(parts, len(members) // 2)) if fresh else 1
        for g in range(split):
            part = members[len(members) * g // split: len(members) * (g + 1) // split]
            grouped.append({"name": "group:" + part[0]["name"], "members": part})
            placed.update(t["name"] for t in part)
    log.info("the replicas of %d points stepped together, in %d groups", len(together),
             len(grouped))
    out = grouped + [t for t in tasks if t["name"] not in placed]
    return sorted(out, key=lambda t: order.get(t.get("members", [t])[0]["name"], -1))


def point_results(result: Mapping[str, Any], members: Mapping[str, list[str]]) -> list[dict]:
    """A task's result as the points' results: a group's members', or the one point's. A
    group whose worker returned nothing (it died, a Dask task was lost) gives each member its
    error."""
    if "group" in result:
        return list(result["group"])
    names = members.get(result["name"])
    if names is None:
        return [dict(result)]
    return [{**result, "name": name} for name in names]
