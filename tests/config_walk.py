"""The walk of a run configuration through the package (issue 31's measure), as data.

:func:`walk` runs one short ``knotmm.workflow.run`` under ``sys.setprofile`` and keeps every
call of a function of ``knotmm`` that is handed the run configuration: a
:class:`knotmm.config.RunConfig` among its arguments (``self`` included), or, with
``derived=True``, also one of the run plan's typed pieces (:mod:`knotmm.plan`: ``RunPlan``,
``Stepping``, ``TemplateSpec``, ``Placement``, ``Output``, ``RunResources``). Each kept call
is a step of the walk, named by the module and the layer of its function (the layers of
``tests/test_layout.py``, which ``docs/architecture.md`` lists) and by those of its caller
(the nearest frame of ``knotmm`` below it on the stack).

:class:`Walk` counts, per run:

* ``config_entries``: steps into ``knotmm/config.py`` from another module, and
  ``config_entries_after_plan``: those after :func:`knotmm.plan.prepare` returned;
* ``climbs``: steps whose function is in a higher layer than their caller's (a call back
  up the layers: a callback, an object of a higher layer called from below);
* ``stays``, ``stay_climbs``, ``returns``, ``config_stays``: the walk read as a sequence of
  stays (a run of consecutive steps in one module), the number of stays that lie in a higher
  layer than the one before, of stays in a module the walk had left before, and of stays in
  ``knotmm/config.py``.

Run as a script (``python tests/config_walk.py``) it prints these numbers.
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "knotmm"
sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_layout import LAYER_OF  # noqa: E402 - the one list of layers


def module_of(filename: str) -> str | None:
    """``knotmm.x.y`` of a source file of the package, else None."""
    try:
        rel = Path(filename).resolve().relative_to(PACKAGE.parent)
    except ValueError:
        return None
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str) -> int:
    parts = module.split(".")
    return LAYER_OF.get(parts[1], -1) if len(parts) > 1 else -1


@dataclass
class Walk:
    """The steps of a walk: ``(module, function, caller module, after the plan)``."""

    steps: list[tuple[str, str, str | None, bool]] = field(default_factory=list)
    #: ``(caller module, caller function, key)`` of every ``RunConfig[key]``.
    reads: list[tuple[str | None, str | None, str]] = field(default_factory=list)

    @property
    def config_entries(self) -> int:
        return sum(1 for m, _, c, _ in self.steps if m == "knotmm.config" and c != m)

    @property
    def config_entries_after_plan(self) -> int:
        return sum(1 for m, _, c, after in self.steps
                   if after and m == "knotmm.config" and c != m)

    def after_plan(self) -> list[str]:
        """``module.function <- caller`` of each step into config.py after the plan."""
        return [f"{m}.{f} <- {c}" for m, f, c, after in self.steps
                if after and m == "knotmm.config" and c != m]

    @property
    def climb_list(self) -> list[str]:
        return [f"{c} -> {m}.{f}" for m, f, c, _ in self.steps
                if c is not None and layer_of(m) > layer_of(c) >= 0]

    @property
    def climbs(self) -> int:
        return len(self.climb_list)

    def stay_modules(self) -> list[str]:
        stays: list[str] = []
        for m, *_ in self.steps:
            if not stays or stays[-1] != m:
                stays.append(m)
        return stays

    @property
    def stays(self) -> int:
        return len(self.stay_modules())

    @property
    def stay_climbs(self) -> int:
        s = self.stay_modules()
        return sum(1 for a, b in zip(s, s[1:]) if layer_of(b) > layer_of(a))  # noqa: B905

    @property
    def returns(self) -> int:
        seen: set[str] = set()
        n = 0
        for m in self.stay_modules():
            n += m in seen
            seen.add(m)
        return n

    def summary(self) -> dict[str, int]:
        return {"steps": len(self.steps), "files": len({m for m, *_ in self.steps}),
                "stays": self.stays, "returns": self.returns,
                "config_stays": self.stay_modules().count("knotmm.config"),
                "stay_climbs": self.stay_climbs, "climbs": self.climbs,
                "config_entries": self.config_entries,
                "config_entries_after_plan": self.config_entries_after_plan}


def _carriers(derived: bool) -> tuple[type, ...]:
    from knotmm.config import RunConfig

    if not derived:
        return (RunConfig,)
    import knotmm.plan as plan
    from knotmm.shapes.resources import RunResources

    pieces = [getattr(plan, n) for n in ("RunPlan", "Stepping", "TemplateSpec", "Placement",
                                         "Output") if hasattr(plan, n)]
    return (RunConfig, RunResources, *pieces)


def _handed(frame, carriers) -> bool:
    """Whether a frame at its call was handed one of ``carriers`` (an argument, a value
    in ``*args``/``**kwargs``)."""
    code = frame.f_code
    n = code.co_argcount + code.co_kwonlyargcount
    names = list(code.co_varnames[:n])
    if code.co_flags & 0x04:  # *args
        names.append(code.co_varnames[n])
        n += 1
    if code.co_flags & 0x08:  # **kwargs
        names.append(code.co_varnames[n])
    local = frame.f_locals
    for name in names:
        value = local.get(name)
        if isinstance(value, carriers):
            return True
        if isinstance(value, tuple) and any(isinstance(v, carriers) for v in value):
            return True
        if isinstance(value, dict) and any(isinstance(v, carriers) for v in value.values()):
            return True
    return False


def walk(cfg, directory, derived: bool = False, call=None) -> Walk:
    """The walk of ``cfg`` through ``knotmm.workflow.run(cfg, directory)``, or of every
    run configuration through ``call()`` when given."""
    from knotmm.workflow import run

    if call is None:
        def call():
            run(cfg, directory, progress=False)

    carriers = _carriers(derived)
    found = Walk()
    state = {"after": False}
    prepare_code = None
    import knotmm.plan as plan

    prepare_code = plan.prepare.__code__

    def profile(frame, event, arg):
        if event == "return" and frame.f_code is prepare_code:
            state["after"] = True
            return
        if event != "call":
            return
        module = module_of(frame.f_code.co_filename)
        if module is None or not _handed(frame, carriers):
            return
        caller = frame.f_back
        while caller is not None and module_of(caller.f_code.co_filename) is None:
            caller = caller.f_back
        where = None if caller is None else module_of(caller.f_code.co_filename)
        found.steps.append((module, frame.f_code.co_name, where, state["after"]))
        if module == "knotmm.config" and frame.f_code.co_name == "__getitem__":
            found.reads.append((where, caller and caller.f_code.co_qualname,
                                str(frame.f_locals.get(frame.f_code.co_varnames[1]))))

    sys.setprofile(profile)
    try:
        call()
    finally:
        sys.setprofile(None)
    return found


def short_run():
    """The run file of the measure: 40 beads, 0.5 tau_d, the default checks."""
    from knotmm.config import RunConfig

    return RunConfig.from_dict({"knot": {"beads": 40}, "run": {"duration": 0.5}})


if __name__ == "__main__":  # pragma: no cover - a measuring tool
    import tempfile

    for derived in (False, True):
        with tempfile.TemporaryDirectory() as tmp:
            w = walk(short_run(), Path(tmp) / "r", derived=derived)
        print("derived" if derived else "RunConfig", w.summary())
        print("  climbs:", Counter(w.climb_list).most_common())
        print("  config after plan:", Counter(w.after_plan()).most_common())
