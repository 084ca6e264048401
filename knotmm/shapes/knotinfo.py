"""Named knots: built-in braid words and the optional KnotInfo tables.

Any knot can be drawn as a closed braid (``docs/model.md``, "Starting shapes"). The
experiments' knots (3_1, 4_1, 5_1, 5_2, 6_1, 7_1) have built-in braid words
(:data:`BUILTIN_BRAIDS`); every other tabulated knot (up to 13 crossings) comes from the
optional ``database_knotinfo`` package, read once and cached.
"""

from __future__ import annotations

import functools
import json
import re
from typing import Any

from knotmm.errors import TemplateError
from knotmm.knots.chirality import normalise_knot_name

__all__ = [
    "BUILTIN_BRAIDS",
    "TORUS_NAMES",
    "knotinfo_available",
    "knotinfo_table",
    "list_named_knots",
    "name_order",
    "named_knot_word",
    "normalise_name",
    "symmetry_type",
]

#: Braid words of the experiments' knots, available without ``database_knotinfo``. Each is
#: the word KnotInfo lists; each closes to the named knot (checked with topoly in the tests).
BUILTIN_BRAIDS: dict[str, tuple[int, ...]] = {
    "3_1": (1, 1, 1),
    "4_1": (1, -2, 1, -2),
    "5_1": (1, 1, 1, 1, 1),
    "5_2": (1, 1, 1, 2, -1, 2),
    "6_1": (1, 1, 2, -1, -3, 2, -3),
    "7_1": (1, 1, 1, 1, 1, 1, 1),
}

#: Amphichiral knots among the built-in ones (no handedness to report).
_BUILTIN_AMPHICHIRAL = frozenset({"4_1"})

#: Names topoly gives the torus knots of the study (checked in the tests).
TORUS_NAMES = {
    (2, 3): "3_1",
    (2, 5): "5_1",
    (2, 7): "7_1",
    (2, 9): "9_1",
    (3, 4): "8_19",
    (3, 5): "10_124",
}


def knotinfo_available() -> bool:
    """Whether the optional ``database_knotinfo`` package can be imported."""
    import importlib.util  # noqa: PLC0415

    return importlib.util.find_spec("database_knotinfo") is not None


def normalise_name(name: str) -> str:
    """'5_2', '5.2', ' 5_2 ' -> '5_2'; '11a367' -> '11a_367' (KnotInfo spelling)."""
    return normalise_knot_name(str(name).strip())


@functools.lru_cache(maxsize=1)
def knotinfo_table() -> dict[str, dict[str, Any]]:
    """KnotInfo's knots: name -> {'word': tuple, 'symmetry': str}; {} if not installed."""
    try:
        import database_knotinfo  # noqa: PLC0415 - optional extra
    except ImportError:
        return {}
    table: dict[str, dict[str, Any]] = {}
    for row in database_knotinfo.link_list():
        name = row.get("name", "")
        text = (row.get("braid_notation") or "").replace(" ", "")
        if not re.fullmatch(r"\d+[an]?_\d+", name) or not text.startswith("["):
            continue
        try:
            parsed = json.loads(text)
        except ValueError:
            continue
        options = parsed if parsed and isinstance(parsed[0], list) else [parsed]
        options = [o for o in options if o and all(isinstance(g, int) and g for g in o)]
        if not options:
            continue
        best = min(options, key=lambda o: (max(abs(g) for g in o), len(o)))
        table[name] = {"word": tuple(best), "symmetry": row.get("symmetry_type", "")}
    return table


def list_named_knots() -> list[str]:
    """Names of the knots :func:`named_knot` can build.

    Returns
    -------
    list of str
        The built-in knots (3_1, 4_1, 5_1, 5_2, 6_1, 7_1) and, if ``database_knotinfo`` is
        installed, every knot of the KnotInfo tables (up to 13 crossings), in table order
        (by crossing number).
    """
    names = dict.fromkeys(BUILTIN_BRAIDS)
    names.update(dict.fromkeys(knotinfo_table()))
    return sorted(names, key=name_order)


def name_order(name: str) -> tuple[int, str, int]:
    m = re.fullmatch(r"(\d+)([an]?)_(\d+)", name)
    if not m:
        return (10**6, name, 0)
    return int(m.group(1)), m.group(2), int(m.group(3))


def named_knot_word(name: str, key: str = "name") -> tuple[str, tuple[int, ...], str]:
    """The braid word of a named knot.

    Parameters
    ----------
    name : str
        Knot name, ``"5_2"`` (Rolfsen) or ``"11a_367"`` (KnotInfo, 11-13 crossings).
    key : str, optional
        Argument name used in error messages.

    Returns
    -------
    name : str
        The normalised name.
    word : tuple of int
        Its braid word.
    source : str
        ``"built-in"`` or ``"KnotInfo"``.

    Raises
    ------
    TemplateError
        For a name in neither table; says whether ``database_knotinfo`` is missing.
    """
    if not isinstance(name, str) or not name.strip():
        raise TemplateError(f"{key}={name!r}: expected a knot name such as '5_2'")
    norm = normalise_name(name)
    if norm in BUILTIN_BRAIDS:
        return norm, BUILTIN_BRAIDS[norm], "built-in"
    if norm == "0_1":
        raise TemplateError(
            f"{key}={name!r}: the unknot has no braid word in the tables; knotmm starts from "
            "knots (e.g. '3_1')"
        )
    table = knotinfo_table()
    if norm in table:
        return norm, table[norm]["word"], "KnotInfo"
    builtin = ", ".join(BUILTIN_BRAIDS)
    if not knotinfo_available():
        raise TemplateError(
            f"{key}={name!r} is not a built-in knot ({builtin}); other knots need the optional "
            "package database_knotinfo: pip install 'knotmm[knots]'"
        )
    import difflib  # noqa: PLC0415

    close = difflib.get_close_matches(norm, list(table), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise TemplateError(
        f"{key}={name!r} is not in the KnotInfo tables (knots up to 13 crossings, named like "
        f"'5_2' or '11a_367'){hint}"
    )


def symmetry_type(name: str) -> str:
    """KnotInfo's symmetry type of a knot name ('' when unknown)."""
    if name == "0_1":
        return "fully amphicheiral"
    if name in BUILTIN_BRAIDS:
        return "fully amphicheiral" if name in _BUILTIN_AMPHICHIRAL else "chiral"
    return knotinfo_table().get(name, {}).get("symmetry", "")

