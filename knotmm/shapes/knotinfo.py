"""Named knots: built-in braid words and the optional KnotInfo tables.

Any knot can be drawn as a closed braid (``docs/model.md``, "Starting shapes"). The
experiments' knots (3_1, 4_1, 5_1, 5_2, 6_1, 7_1) have built-in braid words
(:data:`BUILTIN_BRAIDS`); every other tabulated knot (up to 13 crossings) comes from the
optional ``database_knotinfo`` package, read once and cached. Knots with a common name
(trefoil, figure-eight, cinquefoil, ...: :data:`COMMON_NAMES`) can be named by it wherever a
table name is accepted; :func:`resolve_name` is the one place that turns a name into a
table name.
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
    "COMMON_NAMES",
    "TORUS_NAMES",
    "knotinfo_available",
    "knotinfo_table",
    "list_named_knots",
    "name_order",
    "named_knot_word",
    "normalise_name",
    "resolve_name",
    "suggest_names",
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

#: Common names of knots -> their table names (Rolfsen's table, as KnotInfo names them).
COMMON_NAMES: dict[str, str] = {
    "unknot": "0_1",
    "trefoil": "3_1",
    "figure-eight": "4_1",
    "cinquefoil": "5_1",
    "three-twist": "5_2",
    "stevedore": "6_1",
    "miller-institute": "6_2",
    "septafoil": "7_1",
}

#: Other spellings of the common names.
_OTHER_SPELLINGS: dict[str, str] = {
    "figure8": "figure-eight",
    "figure-of-eight": "figure-eight",
    "pentafoil": "cinquefoil",
    "solomon's-seal": "cinquefoil",
    "heptafoil": "septafoil",
}


def _name_key(text: str) -> str:
    """A common name as compared: lower case, letters and digits only, no word 'knot'.

    ``'Figure-Eight knot'`` -> ``'figureeight'``, ``"stevedore's knot"`` -> ``'stevedore'``.
    """
    text = re.sub(r"[\s_-]+knot$", "", str(text).strip().lower()).replace("'s", "")
    return re.sub(r"[^a-z0-9]", "", text)


#: Compared spelling -> (the common name, its table name).
_COMMON_KEYS: dict[str, tuple[str, str]] = {
    **{_name_key(k): (k, v) for k, v in COMMON_NAMES.items()},
    **{_name_key(k): (v, COMMON_NAMES[v]) for k, v in _OTHER_SPELLINGS.items()},
}

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


def resolve_name(name: str) -> str:
    """The table name of a knot name: a common name or a spelling of a table name.

    ``'trefoil'``, ``'Trefoil knot'`` -> ``'3_1'``; ``'figure8'`` -> ``'4_1'``; ``'5.2'`` ->
    ``'5_2'``; ``'11a367'`` -> ``'11a_367'``. A name that is neither comes back normalised
    (:func:`normalise_name`), to be looked up (and refused) by :func:`named_knot_word`.
    """
    common = _COMMON_KEYS.get(_name_key(name))
    return common[1] if common else normalise_name(name)


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
        Knot name, ``"5_2"`` (Rolfsen), ``"11a_367"`` (KnotInfo, 11-13 crossings) or a
        common name (``"trefoil"``, :data:`COMMON_NAMES`).
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
        For a name in neither table, with the names it is close to
        (:func:`suggest_names`); says whether ``database_knotinfo`` is missing.
    """
    if not isinstance(name, str) or not name.strip():
        raise TemplateError(f"{key}={name!r}: expected a knot name such as '5_2' or 'trefoil'")
    norm = resolve_name(name)
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
    hint = suggest_names(norm, list(table) or list(BUILTIN_BRAIDS), complete=bool(table))
    if not knotinfo_available():
        if hint and not re.fullmatch(r"\d+[an]?_\d+", norm):  # a misspelt common name
            raise TemplateError(f"{key}={name!r} is not a knot name{hint}")
        raise TemplateError(
            f"{key}={name!r} is not a built-in knot ({builtin}); other knots need the optional "
            "package database_knotinfo: pip install 'knotmm[knots]'"
        )
    raise TemplateError(
        f"{key}={name!r} is not in the KnotInfo tables (knots up to 13 crossings, named like "
        f"'5_2' or '11a_367', or by a common name such as 'trefoil'){hint}"
    )


def suggest_names(name: str, known: list[str], complete: bool = True) -> str:
    """What to suggest for a knot name that is in no table ('' when nothing is close).

    Parameters
    ----------
    name : str
        The name as :func:`resolve_name` left it.
    known : list of str
        The table names that exist.
    complete : bool, optional
        Whether ``known`` holds every tabulated knot (KnotInfo) or only the built-in ones;
        only a complete table can say which knots of a crossing number exist.

    Returns
    -------
    str
        ``"; the knots with 5 crossings are 5_1, 5_2"`` for a table-style name (a name
        with the same crossing number first), ``"; did you mean 'trefoil' (3_1)?"`` for a
        misspelt common name, else the closest table name or ''.
    """
    import difflib  # noqa: PLC0415

    m = re.fullmatch(r"(\d+)([an]?)_(\d+)", name)
    if m and complete:
        crossings, letter = int(m.group(1)), m.group(2)
        same = [n for n in known if name_order(n)[0] == crossings]
        if not same:
            if crossings < 3:
                return "; only the unknot (0_1) has fewer than 3 crossings: the first knot is 3_1"
            largest = max((name_order(n)[0] for n in known), default=0)
            return f"; the tables hold knots of 3 to {largest} crossings"
        if letter:
            same = [n for n in same if name_order(n)[1] == letter] or same
        else:  # 11_5: KnotInfo names knots of 11 and more crossings 11a_5 and 11n_5
            alike = [n for n in same if name_order(n)[2] == int(m.group(3))]
            if alike:
                return f"; did you mean {' or '.join(repr(n) for n in alike)}?"
        listing = ", ".join(same) if len(same) <= 8 else (
            f"{same[0]} ... {same[-1]} ({len(same)} knots)"
        )
        return f"; the knots with {crossings} crossings are {listing}"
    if m:
        return ""
    close = difflib.get_close_matches(_name_key(name), list(_COMMON_KEYS), n=1, cutoff=0.6)
    if close:
        common, table_name = _COMMON_KEYS[close[0]]
        return f"; did you mean '{common}' ({table_name})?"
    close = difflib.get_close_matches(name, known, n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def symmetry_type(name: str) -> str:
    """KnotInfo's symmetry type of a knot name ('' when unknown)."""
    if name == "0_1":
        return "fully amphicheiral"
    if name in BUILTIN_BRAIDS:
        return "fully amphicheiral" if name in _BUILTIN_AMPHICHIRAL else "chiral"
    return knotinfo_table().get(name, {}).get("symmetry", "")

