"""Tests of knotmm.knots.chirality: one spelling of knot types and handedness."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.knots.chirality import (
    ACHIRAL,
    AMPHICHIRAL,
    LEFT,
    RIGHT,
    UNKNOWN,
    handedness,
    is_signed,
    knot_handedness,
    mirror_type,
    normalise_knot_name,
    parse_knot_type,
    signed_knot_type,
    unsigned_knot_type,
)
from knotmm.knots.identify import identify_knot, topoly_available
from knotmm.knots.writhe import writhe

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")


def test_normalise_knot_name():
    assert normalise_knot_name("11a367") == "11a_367"
    assert normalise_knot_name("+11N34|-5.1#+3_1") == "+11n_34|-5_1#+3_1"
    assert normalise_knot_name("unknown") == "unknown"


def test_parse_knot_type():
    assert parse_knot_type("+3_1") == ("+", "3_1")
    assert parse_knot_type("-5.1") == ("-", "5_1")
    assert parse_knot_type("4_1") == ("", "4_1")
    assert parse_knot_type("-11a367") == ("-", "11a_367")
    for bad in ("unknown", "+3_1#-3_1", "5_1|10_132", "right"):
        with pytest.raises(ValueError, match="one prime knot"):
            parse_knot_type(bad)


def test_signs_of_composites_and_candidates():
    assert mirror_type("+3_1#-5_2") == "-3_1#+5_2"
    assert mirror_type("4_1") == "4_1" and mirror_type(UNKNOWN) == UNKNOWN
    assert mirror_type(None) is None
    assert unsigned_knot_type("+3_1#-3_1|+6_1") == "3_1#3_1|6_1"
    assert is_signed("-5_1") and is_signed("4_1#+3_1") and not is_signed("4_1")
    for name in ("+3_1", "-3_1#+5_2", "4_1", "+5_1|+10_132"):
        assert mirror_type(mirror_type(name)) == name
        assert unsigned_knot_type(mirror_type(name)) == unsigned_knot_type(name)


def test_handedness_words():
    assert (handedness(2.1), handedness(-0.3), handedness(0.0)) == (RIGHT, LEFT, None)
    assert handedness(0.05, threshold=0.1) is None
    assert knot_handedness("+3_1") == RIGHT and knot_handedness("-5_1") == LEFT
    assert knot_handedness("4_1") == ACHIRAL and knot_handedness("0_1") == ACHIRAL
    assert knot_handedness("+3_1#-3_1") == UNKNOWN  # the square knot: both hands
    assert knot_handedness(None) == UNKNOWN and knot_handedness(UNKNOWN) == UNKNOWN


def test_signed_knot_type_from_the_writhe():
    assert signed_knot_type("5_1", -4.2) == "-5_1"
    assert signed_knot_type("3_1#3_1", 1.0) == "+3_1#+3_1"
    assert signed_knot_type("+3_1", -1.0) == "+3_1"  # a sign given is kept
    assert signed_knot_type("4_1", 1.0) == "4_1" and signed_knot_type("0_1", -1.0) == "0_1"
    assert signed_knot_type("9_42", 1.0, amphichiral=True) == "9_42"
    assert signed_knot_type("4_1", 1.0, amphichiral=False) == "+4_1"
    assert signed_knot_type(UNKNOWN, 1.0) == UNKNOWN and signed_knot_type(None, 1.0) is None


def test_amphichiral_table_is_knotinfos():
    """Every knot up to 10 crossings that KnotInfo calls amphicheiral, and no other."""
    knotinfo = pytest.importorskip("database_knotinfo")
    rows = knotinfo.link_list()
    expected = {"0_1"} | {
        r["name"]
        for r in rows[1:]
        if str(r.get("crossing_number", "")).isdigit()
        and int(r["crossing_number"]) <= 10
        and "amphicheiral" in (r.get("symmetry_type") or "")
    }
    assert AMPHICHIRAL == expected


@needs_topoly
@pytest.mark.parametrize(("p", "q"), [(2, 3), (2, 5), (2, 7)])
@pytest.mark.parametrize("mirror", [False, True])
def test_signed_type_from_writhe_agrees_with_topolys_chiral_polynomial(p, q, mirror, torus_curve):
    """The writhe's sign and topoly's chiral HOMFLY-PT give one and the same signed name."""

    def _torus(p, q, mirror):
        x = torus_curve(p, q, 150)
        return x * np.array([1.0, 1.0, -1.0]) if mirror else x

    x = _torus(p, q, mirror=mirror)
    chiral = identify_knot(x, chiral=True)
    assert signed_knot_type(identify_knot(x), writhe(x)) == chiral
    assert knot_handedness(chiral) == handedness(writhe(x)) == (LEFT if mirror else RIGHT)
    assert mirror_type(chiral) == identify_knot(_torus(p, q, mirror=not mirror), chiral=True)
