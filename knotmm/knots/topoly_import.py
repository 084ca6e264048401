"""Import topoly in the knot worker without the plotting libraries its package pulls in.

topoly's package ``__init__`` imports its drawing, map and polygon-generation modules, and
with them matplotlib (pyplot, mplot3d, axes_grid1), ``scipy.ndimage``, ``scipy.interpolate``
and ``scipy.special``: about 1 s of its 1.4 s import on this project's machines, none of it
used by the HOMFLY-PT call the worker makes. A run that ends before the worker is ready
waits for that import (``docs/architecture.md``, "Start-up").

:func:`import_topoly` imports topoly with those modules (:data:`STAND_IN_MODULES`) replaced,
for the length of the import only, by inert stand-ins: module objects whose every attribute
is a :class:`_StandIn`, which accepts whatever topoly does with it at import (calls, item
assignment, subclassing). Afterwards the stand-ins leave ``sys.modules`` (a later import of
matplotlib in the worker gets the real one), and any use of a stand-in that topoly kept
raises :class:`StandInUsed`; :func:`knotmm.knots.homfly.identify_here` then imports topoly
in full (:func:`import_topoly_in_full`) and repeats the call. A light import that fails
for any reason falls back to the full import at once. So the stand-ins can make topoly
slower to start in the worst case, never give a different answer.

Only the knot worker (:mod:`knotmm.knots.worker`) calls this: the stand-ins are
process-wide for the length of the import.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import logging
import sys
import types

__all__ = ["STAND_IN_MODULES", "StandInUsed", "import_topoly", "import_topoly_in_full"]

log = logging.getLogger(__name__)

#: Packages topoly imports only for drawing, knot maps and random polygons.
STAND_IN_MODULES = (
    "matplotlib",
    "mpl_toolkits",
    "scipy.ndimage",
    "scipy.interpolate",
    "scipy.special",
)


class StandInUsed(BaseException):  # noqa: N818 - not an error of the caller's making
    """topoly used a module that the light import replaced by a stand-in.

    A ``BaseException``, so that no ``except Exception`` inside topoly takes it for one of
    its own failures and carries on with a different answer.
    """


_state = {"importing": False}


def _touched(what: str):
    if not _state["importing"]:
        raise StandInUsed(f"topoly used {what}, which the light import did not load")


class _StandInType(type):
    """Class-level behaviour of :class:`_StandIn` (``plt.rcParams[...] = ...`` at import)."""

    def __getattr__(cls, name):
        if name.startswith("__"):
            raise AttributeError(name)
        _touched(f"{cls.__name__}.{name}")
        return _StandIn

    def __getitem__(cls, key):
        _touched(cls.__name__)
        return _StandIn

    def __setitem__(cls, key, value):
        _touched(cls.__name__)


class _StandIn(metaclass=_StandInType):
    """Whatever a stand-in module's attribute is: callable, subscriptable, subclassable."""

    def __init__(self, *args, **kwargs):
        _touched(type(self).__name__)

    def __call__(self, *args, **kwargs):
        _touched(type(self).__name__)
        return _StandIn()

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        _touched(f"{type(self).__name__}.{name}")
        return _StandIn()

    def __getitem__(self, key):
        _touched(type(self).__name__)
        return _StandIn()

    def __setitem__(self, key, value):
        _touched(type(self).__name__)


class _StandInModule(types.ModuleType):
    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        _touched(f"{self.__name__}.{name}")
        return _StandIn


def _stood_in_for(name: str) -> bool:
    """Whether the light import stands in for module ``name``: one of
    :data:`STAND_IN_MODULES` or below one, unless that package is imported for real."""
    for package in STAND_IN_MODULES:
        if name == package or name.startswith(package + "."):
            real = sys.modules.get(package)
            return real is None or isinstance(real, _StandInModule)
    return False


class _StandInFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname, path, target=None):
        if _stood_in_for(fullname):
            return importlib.machinery.ModuleSpec(fullname, self, is_package=True)
        return None

    def create_module(self, spec):
        module = _StandInModule(spec.name)
        module.__path__ = []
        return module

    def exec_module(self, module):
        pass


def _forget(predicate) -> None:
    for name in [n for n in sys.modules if predicate(n)]:
        del sys.modules[name]


def _forget_stand_ins() -> None:
    """Take the stand-ins out of ``sys.modules`` and off the real packages above them
    (``scipy.ndimage`` as an attribute of the real ``scipy``)."""
    stand_ins = {n: m for n, m in sys.modules.items() if isinstance(m, _StandInModule)}
    for name, module in stand_ins.items():
        del sys.modules[name]
        parent, _, child = name.rpartition(".")
        if parent and getattr(sys.modules.get(parent), child, None) is module:
            delattr(sys.modules[parent], child)


def _is_topoly(name: str) -> bool:
    return name == "topoly" or name.startswith("topoly.")


def import_topoly_in_full() -> types.ModuleType:
    """Import topoly as its package does, with matplotlib and scipy's modules (seconds).

    A lightly imported topoly is forgotten first (its modules hold stand-ins).
    """
    if getattr(sys.modules.get("topoly"), "_knotmm_light", False):
        _forget(_is_topoly)
    import topoly  # noqa: PLC0415 - optional extra, imported lazily

    return topoly


def import_topoly() -> types.ModuleType:
    """Import topoly with its plotting-only dependencies stood in for (see the module text).

    Returns the topoly module; one imported already (light or full) is returned as it is.
    Raises ``ImportError`` when topoly is not installed.
    """
    if "topoly" in sys.modules:
        return sys.modules["topoly"]
    finder = _StandInFinder()
    sys.meta_path.insert(0, finder)
    _state["importing"] = True
    try:
        import topoly  # noqa: PLC0415 - optional extra, imported lazily
    except ImportError:
        _forget(_is_topoly)
        raise
    except Exception as exc:  # noqa: BLE001 - any failure: the full import decides
        log.debug("light import of topoly failed (%s: %s); importing it in full",
                  type(exc).__name__, exc)
        _forget(_is_topoly)
        topoly = None
    finally:
        _state["importing"] = False
        sys.meta_path.remove(finder)
        _forget_stand_ins()
    if topoly is None:
        return import_topoly_in_full()
    topoly._knotmm_light = True
    return topoly
