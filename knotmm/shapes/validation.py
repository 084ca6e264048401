"""Checks of the arguments that describe a knot template, with messages naming the key.

Every public shape function and :func:`knotmm.shapes.builder.build_template` check their
arguments here. Messages name the argument as the caller knows it: the plain argument name
(``beads``) for the Python functions, the dotted run-file key (``knot.beads``) for run
files; :data:`PLAIN_NAMES` and :data:`RUN_FILE_KEYS` map one to the other.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np

from knotmm.errors import TemplateError
from knotmm.shapes.curves import braid_cycles

__all__ = [
    "PLAIN_NAMES",
    "RUN_FILE_KEYS",
    "check_int",
    "check_positive",
    "check_torus",
    "check_word",
    "parse_word_text",
]

#: Argument names as the public functions call them.
PLAIN_NAMES = {
    "p": "p",
    "q": "q",
    "word": "word",
    "name": "name",
    "path": "path",
    "frame": "frame",
    "topology": "topology",
    "beads": "beads",
    "minor_radius": "minor_radius",
    "major_radius": "major_radius",
    "bond_length": "bond_length",
    "lj_sigma": "lj_sigma",
    "perturbation": "perturbation",
}
#: The same arguments as run-file keys (build_template's messages).
RUN_FILE_KEYS = {
    **{k: f"knot.{k}" for k in PLAIN_NAMES},
    "bond_length": "model.bond_length",
    "lj_sigma": "model.lj_sigma",
}


def check_int(value, name: str, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TemplateError(f"{name}={value!r}: expected an integer")
    if minimum is not None and value < minimum:
        raise TemplateError(f"{name}={value}: must be >= {minimum}")
    return int(value)


def check_positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TemplateError(f"{name}={value!r}: expected a number")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise TemplateError(f"{name}={value!r}: expected a finite number > 0")
    return value


def check_torus(p, q, names: Mapping[str, str]) -> tuple[int, int]:
    p = check_int(p, names["p"])
    q = check_int(q, names["q"])
    if p < 1 or q < 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: both must be positive integers >= 2"
        )
    if p == 1 or q == 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: T({p},{q}) is the unknot; "
            "use p >= 2 and q >= 2 (T(2,3) is the trefoil)"
        )
    g = math.gcd(p, q)
    if g != 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: T({p},{q}) is a link of {g} components, not "
            f"a knot (p and q share the factor {g}); p and q must be coprime, e.g. "
            f"T({p},{_next_coprime(p, q)})"
        )
    return p, q


def _next_coprime(p: int, q: int) -> int:
    q += 1
    while math.gcd(p, q) != 1:
        q += 1
    return q


def check_word(word, names: Mapping[str, str]) -> tuple[int, ...]:
    key = names["word"]
    if word is None:
        raise TemplateError(f"{key} is not set: give a braid word, e.g. [1, -2, 1, -2]")
    if isinstance(word, str):
        word = parse_word_text(word, key)
    try:
        items = list(word)
    except TypeError:
        raise TemplateError(f"{key}={word!r}: expected a list of integers") from None
    if not items:
        raise TemplateError(f"{key}=[]: a braid word needs at least one generator")
    for g in items:
        if isinstance(g, bool) or not isinstance(g, (int, np.integer)):
            raise TemplateError(f"{key}={items!r}: expected a list of integers, got {g!r}")
        if g == 0:
            raise TemplateError(
                f"{key}={items!r}: generator 0 does not exist; use +-1, +-2, ... "
                "(sigma_i, or its inverse when negative)"
            )
    items = [int(g) for g in items]
    strands = max(abs(g) for g in items) + 1
    used = {abs(g) for g in items}
    missing = sorted(set(range(1, strands)) - used)
    cycles = braid_cycles(items, strands)
    if len(cycles) > 1:
        hint = (
            f"generator {missing[0]} never appears, so the strands split apart"
            if missing
            else "an odd number of crossings between some strands would join them"
        )
        raise TemplateError(
            f"{key}={items!r} closes to a link of {len(cycles)} components, not a knot "
            f"({hint}); the strand permutation must be a single cycle"
        )
    return tuple(items)


def parse_word_text(text: str, key: str) -> list[int]:
    parts = [p for p in re.split(r"[\s,]+", text.strip().strip("[](){}")) if p]
    try:
        return [int(p) for p in parts]
    except ValueError:
        raise TemplateError(
            f"{key}={text!r}: expected signed generator indices such as 1,-2,1,-2"
        ) from None

