"""Common knot names (trefoil, figure-eight, ...) and the suggestions for unknown names."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.errors import TemplateError
from knotmm.shapes import knotinfo
from knotmm.shapes.builder import build_template
from knotmm.shapes.geometry import named_knot

needs_knotinfo = pytest.mark.skipif(
    not knotinfo.knotinfo_available(), reason="database_knotinfo not installed"
)


@pytest.mark.parametrize(
    ("name", "table_name"),
    [
        ("unknot", "0_1"),
        ("trefoil", "3_1"),
        ("Trefoil knot", "3_1"),
        ("figure-eight", "4_1"),
        ("figure8", "4_1"),
        ("Figure eight knot", "4_1"),
        ("figure-of-eight", "4_1"),
        ("cinquefoil", "5_1"),
        ("pentafoil", "5_1"),
        ("Solomon's seal", "5_1"),
        ("three-twist", "5_2"),
        ("stevedore", "6_1"),
        ("stevedore's knot", "6_1"),
        ("Miller Institute knot", "6_2"),
        ("septafoil", "7_1"),
        ("heptafoil", "7_1"),
        ("5.2", "5_2"),
        ("11A367", "11a_367"),
        ("3_1", "3_1"),
    ],
)
def test_resolve_name(name, table_name):
    assert knotinfo.resolve_name(name) == table_name


def test_every_common_name_is_a_table_name():
    for common, table_name in knotinfo.COMMON_NAMES.items():
        assert knotinfo.resolve_name(common) == table_name
        assert knotinfo.normalise_name(table_name) == table_name


def test_common_names_build_the_same_shape_as_table_names():
    np.testing.assert_array_equal(named_knot("trefoil", 90), named_knot("3_1", 90))
    np.testing.assert_array_equal(named_knot("figure-eight", 100), named_knot("4_1", 100))
    assert knotinfo.named_knot_word("Stevedore")[:2] == ("6_1", knotinfo.BUILTIN_BRAIDS["6_1"])


def test_run_file_name_is_resolved_and_recorded_as_the_table_name():
    cfg = RunConfig.from_dict({"knot": {"kind": "knotinfo", "name": "cinquefoil", "beads": 100}})
    tpl = build_template(cfg)
    assert tpl.resolved["knot.name"] == "5_1"
    assert tpl.description.startswith("5_1 (braid")


def test_unknot_is_named_but_refused_as_a_start():
    with pytest.raises(TemplateError, match=r"name='unknot': the unknot has no braid word"):
        named_knot("unknot", 60)


@needs_knotinfo
@pytest.mark.parametrize(
    ("name", "hint"),
    [
        ("5_3", "the knots with 5 crossings are 5_1, 5_2"),
        ("7_9", "the knots with 7 crossings are 7_1, 7_2, 7_3, 7_4, 7_5, 7_6, 7_7"),
        ("8_25", "the knots with 8 crossings are 8_1 ... 8_21 (21 knots)"),
        ("11a_999", "11a_1 ... 11a_367 (367 knots)"),
        ("11_5", "did you mean '11a_5' or '11n_5'?"),
        ("14_1", "the tables hold knots of 3 to 13 crossings"),
        ("2_1", "only the unknot (0_1) has fewer than 3 crossings"),
        ("trefiol", "did you mean 'trefoil' (3_1)?"),
        ("figure-eigth", "did you mean 'figure-eight' (4_1)?"),
        ("stevdore", "did you mean 'stevedore' (6_1)?"),
        ("cinquefoyle", "did you mean 'cinquefoil' (5_1)?"),
    ],
)
def test_suggestions_that_make_sense(name, hint):
    with pytest.raises(TemplateError) as info:
        knotinfo.named_knot_word(name)
    message = str(info.value)
    assert hint in message and "\n" not in message
    assert "9_3" not in message


def test_misspelt_common_name_without_knotinfo(monkeypatch):
    monkeypatch.setattr(knotinfo, "knotinfo_table", lambda: {})
    monkeypatch.setattr(knotinfo, "knotinfo_available", lambda: False)
    with pytest.raises(TemplateError, match=r"did you mean 'trefoil' \(3_1\)\?"):
        knotinfo.named_knot_word("trefiol")
    with pytest.raises(TemplateError, match=r"name='8_17'.*database_knotinfo"):
        knotinfo.named_knot_word("8_17")
    assert knotinfo.named_knot_word("trefoil")[0] == "3_1"


def test_cli_template_accepts_a_common_name(capsys):
    assert main(["template", "trefoil", "--beads", "90"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("knot") and "3_1 (braid [1, 1, 1], built-in)" in out


@needs_knotinfo
def test_cli_template_suggests_same_crossing_number(capsys):
    assert main(["template", "5_3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "5_1, 5_2" in err and "9_3" not in err


def test_cli_list_shows_common_names(capsys):
    assert main(["template", "--list"]) == 0
    out = capsys.readouterr().out
    assert "trefoil (3_1)" in out and "figure-eight (4_1)" in out
