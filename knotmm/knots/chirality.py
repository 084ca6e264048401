"""The one vocabulary of knot types and handedness.

Knot types are spelled as the KnotInfo tables spell them (``"3_1"``, ``"11a_367"``), with the
handedness of a chiral knot as a sign in front: ``"+3_1"`` is the right-handed trefoil (the
unmirrored T(2,3), positive writhe), ``"-3_1"`` its mirror image. A knot equal to its mirror
image (amphichiral: ``"4_1"``) has no sign, the unknot is ``"0_1"``, and a knot that could not
be named is ``"unknown"``. Composites join their factors with ``"#"`` (``"+3_1#-3_1"``);
knots that topoly's HOMFLY-PT polynomial cannot tell apart are listed with ``"|"``
(``"+5_1|+10_132"``).

Handedness is one word: ``"right"`` (positive writhe, ``"+"``), ``"left"`` (negative,
``"-"``), ``"achiral"`` (an amphichiral knot or the unknot) or ``"unknown"``. Wherever knotmm
shows a knot type (run.toml, analysis.json, the command line) it is the signed name.

Examples
--------
>>> signed_knot_type("5_1", writhe=-4.2)
'-5_1'
>>> signed_knot_type("4_1", writhe=1.0)
'4_1'
>>> mirror_type("+3_1#-5_2")
'-3_1#+5_2'
>>> handedness(-4.2), knot_handedness("+3_1"), knot_handedness("4_1")
('left', 'right', 'achiral')
>>> parse_knot_type("-3_1")
('-', '3_1')
"""

from __future__ import annotations

import re

__all__ = [
    "ACHIRAL",
    "AMPHICHIRAL",
    "LEFT",
    "RIGHT",
    "UNKNOT",
    "UNKNOWN",
    "handedness",
    "is_signed",
    "knot_handedness",
    "mirror_type",
    "normalise_knot_name",
    "parse_knot_type",
    "signed_knot_type",
    "unsigned_knot_type",
]

#: The unknot.
UNKNOT = "0_1"
#: A knot type that could not be named (not in topoly's tables, or too many crossings); also
#: a handedness that cannot be told.
UNKNOWN = "unknown"
#: Handedness words.
RIGHT, LEFT, ACHIRAL = "right", "left", "achiral"

#: Prime knots up to 10 crossings equal to their mirror image (KnotInfo's symmetry types
#: "fully amphicheiral" and "negative amphicheiral"); every other one is chiral.
AMPHICHIRAL = frozenset(
    {
        "0_1", "4_1", "6_3", "8_3", "8_9", "8_12", "8_17", "8_18",
        "10_17", "10_33", "10_37", "10_43", "10_45", "10_79", "10_81", "10_88", "10_99",
        "10_109", "10_115", "10_118", "10_123",
    }
)

_SIGN_TO_HANDEDNESS = {"+": RIGHT, "-": LEFT}
_PRIME = re.compile(r"([+-]?)(\d+[an]?_\d+)")


def normalise_knot_name(name: str) -> str:
    """Spell a knot name as the KnotInfo tables do, keeping chirality signs.

    ``'11a367'`` (topoly) -> ``'11a_367'``; ``'5.2'`` -> ``'5_2'``; composites and lists of
    candidates are handled part by part (``'+3_1#-3_1'``, ``'10_132|5_1'``).

    Parameters
    ----------
    name : str

    Returns
    -------
    str
    """

    def one(part: str) -> str:
        m = re.fullmatch(r"([+-]?)(\d+)\s*[_.]\s*(\d+)", part.strip())
        if m:
            return f"{m.group(1)}{int(m.group(2))}_{int(m.group(3))}"
        m = re.fullmatch(r"([+-]?)(\d+)\s*([anAN])\s*_?\s*(\d+)", part.strip())
        if m:
            return f"{m.group(1)}{int(m.group(2))}{m.group(3).lower()}_{int(m.group(4))}"
        return part.strip()

    return "|".join("#".join(one(p) for p in alt.split("#")) for alt in name.split("|"))


def parse_knot_type(name: str) -> tuple[str, str]:
    """Split a prime knot type into its sign and its table name.

    Parameters
    ----------
    name : str
        ``"+3_1"``, ``"-5_1"``, ``"4_1"``, ``"3.1"`` (normalised first).

    Returns
    -------
    (sign, base) : (str, str)
        ``sign`` is ``"+"``, ``"-"`` or ``""`` (unsigned); ``base`` the KnotInfo name.

    Raises
    ------
    ValueError
        For a composite, a list of candidates, ``"unknown"`` or anything else that is not
        one prime knot name.
    """
    text = normalise_knot_name(str(name))
    m = _PRIME.fullmatch(text)
    if m is None:
        raise ValueError(
            f"knot type {name!r}: expected one prime knot such as '+3_1', '-5_1' or '4_1'"
        )
    return m.group(1), m.group(2)


def _parts(name: str):
    """Each prime factor of each candidate of ``name``, with its separators."""
    return re.split(r"([|#])", name)


def is_signed(name: str | None) -> bool:
    """Whether any factor of ``name`` carries a handedness sign."""
    return name is not None and any(p[:1] in "+-" and p[1:2].isdigit() for p in _parts(name))


def unsigned_knot_type(name: str | None) -> str | None:
    """The knot type without handedness signs: ``'+3_1#-3_1'`` -> ``'3_1#3_1'``."""
    if name is None:
        return None
    return "".join(p[1:] if p[:1] in "+-" and p[1:2].isdigit() else p for p in _parts(name))


def mirror_type(name: str | None) -> str | None:
    """The knot type of the mirror image: every sign flipped, unsigned factors kept.

    ``'+3_1'`` -> ``'-3_1'``, ``'+3_1#-5_2'`` -> ``'-3_1#+5_2'``, ``'4_1'`` -> ``'4_1'``.
    """
    if name is None:
        return None
    flip = {"+": "-", "-": "+"}
    return "".join(
        flip[p[0]] + p[1:] if p[:1] in flip and p[1:2].isdigit() else p for p in _parts(name)
    )


def handedness(writhe: float, threshold: float = 0.0) -> str | None:
    """``"right"`` for writhe above ``threshold``, ``"left"`` below ``-threshold``, else None.

    Parameters
    ----------
    writhe : float
        Writhe of the closed chain (dimensionless).
    threshold : float
        ``|writhe|`` at or below this is too small to call a handedness.
    """
    if writhe > threshold:
        return RIGHT
    if writhe < -threshold:
        return LEFT
    return None


def knot_handedness(name: str | None) -> str:
    """Handedness a knot type states: ``"right"`` (``+``), ``"left"`` (``-``), ``"achiral"``
    (unsigned: amphichiral or the unknot) or ``"unknown"`` (None, ``"unknown"``, a
    composite of both hands or a list of candidates of different hands)."""
    if name is None or name == UNKNOWN:
        return UNKNOWN
    signs = {p[0] for p in _parts(name) if p[:1] in "+-" and p[1:2].isdigit()}
    if not signs:
        return ACHIRAL
    if len(signs) == 1:
        return _SIGN_TO_HANDEDNESS[signs.pop()]
    return UNKNOWN


def signed_knot_type(
    name: str | None, writhe: float, amphichiral: bool | None = None
) -> str | None:
    """A knot type with its handedness sign, taken from the writhe where it has none.

    Signs already present are kept. Each unsigned chiral factor gets ``"+"`` for positive
    writhe and ``"-"`` for negative; amphichiral factors (:data:`AMPHICHIRAL`, or all of
    them when ``amphichiral`` is true) stay unsigned, as do ``"unknown"`` and None.

    Parameters
    ----------
    name : str or None
        ``"5_1"``, ``"+3_1"``, ``"3_1#3_1"``, ``"5_1|10_132"``.
    writhe : float
        Writhe of the chain (its sign is the handedness of a chiral torus knot).
    amphichiral : bool, optional
        What the caller knows (a KnotInfo symmetry type); None: :data:`AMPHICHIRAL` decides.

    Returns
    -------
    str or None
    """
    if name is None or name == UNKNOWN or amphichiral:
        return name
    sign = "+" if writhe > 0 else "-"

    def one(part: str) -> str:
        if part in "|#" or part[:1] in "+-" or not part[:1].isdigit():
            return part
        if part == UNKNOT or (amphichiral is None and part in AMPHICHIRAL):
            return part
        return sign + part

    return "".join(one(p) for p in _parts(normalise_knot_name(name)))
