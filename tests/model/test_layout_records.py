"""ChainLayout: any number of chains (BUG-15), its run.toml record checked (BUG-20), its
chains read back from bonds (BUG-15, BUG-24)."""

from __future__ import annotations

import pytest

from knotmm.errors import KnotmmError, TrajectoryFileError
from knotmm.model.layout import CHAIN_IDS, ChainLayout

TWO = ChainLayout((30, 30), (True, True))
WHERE = r"run\.toml's \[knotmm\.layout\]"


def test_chains_past_62_have_unique_names_and_repeating_pdb_ids():
    assert ChainLayout((3,) * 62).ids == tuple(CHAIN_IDS)
    assert ChainLayout((3,) * 65).ids[62:] == ("AA", "AB", "AC")
    names = ChainLayout((2,) * (62 + 62 * 62 + 5), (False,) * (62 + 62 * 62 + 5)).ids
    assert len(set(names)) == len(names) and max(map(len, names)) == 3
    layout = ChainLayout((4,) * 70, (False,) * 70)
    assert layout.n_chains == 70 and len(set(layout.ids)) == 70
    assert layout.pdb_chain_ids[:2] == ("A", "B") and layout.pdb_chain_ids[62:64] == ("A", "B")
    assert all(len(c) == 1 for c in layout.pdb_chain_ids)
    assert len(layout.bonds()) == 70 * 3


def test_a_layout_record_round_trips_and_agrees_with_its_topology():
    layout = ChainLayout((4,) * 70, (False,) * 70)
    record = layout.to_record()
    assert ChainLayout.from_record(record, 280, expected=layout) == layout
    chains = [{"id": i, "beads": 4, "closed": False} for i in layout.ids]
    assert ChainLayout.from_record(record, 280, chains=chains) == layout
    assert ChainLayout.from_record(None, 60) == ChainLayout.ring(60)


@pytest.mark.parametrize(("record", "message"), [
    ({"lengths": [30, 31], "closed": [True, True]}, r"hold 61 beads, the run's state 60"),
    ({"lengths": "abc", "closed": [True, True]}, r"lengths = 'abc': expected a list"),
    ({"lengths": [30, 30], "closed": "yes"}, r"closed = 'yes': expected a list"),
    ({"lengths": [30, 30], "closed": [True]}, r"closed has 1 entries for 2 chains"),
    ({"lengths": [30, 30], "closed": [1, 0]}, r"expected true or false"),
    ({"lengths": [30, 1.5], "closed": [True, True]}, r"not an integer"),
    ({"lengths": [58, 2], "closed": [True, True]}, r"needs at least 3"),
    ({"closed": [True, True]}, r"lengths = None"),
    ("lengths", r"expected a table"),
    ({"lengths": [20, 40], "closed": [True, True]}, r"disagrees with the run's chains"),
    ({"lengths": [30, 30], "closed": [True, False]}, r"disagrees with the run's chains"),
    ({"lengths": [60], "closed": [True]}, r"disagrees with the run's chains"),
    (None, r"is missing, but the run holds 60 beads in 2 chains"),
])
def test_an_edited_layout_record_is_refused_in_one_line(record, message):
    with pytest.raises(TrajectoryFileError, match=message) as info:
        ChainLayout.from_record(record, 60, expected=TWO)
    text = str(info.value)
    assert isinstance(info.value, KnotmmError) and "\n" not in text
    assert text.startswith("run.toml's [knotmm.layout]")
    if "disagrees" in message or "missing" in message:
        assert "restore" in text and "lengths = [30, 30], closed = [true, true]" in text


def test_the_recorded_chains_catch_an_edit_without_a_topology_file():
    chains = [{"id": "A", "beads": 30, "closed": True}, {"id": "B", "beads": 30, "closed": True}]
    with pytest.raises(TrajectoryFileError, match=WHERE + r" .*disagrees"):
        ChainLayout.from_record({"lengths": [20, 40], "closed": [True, True]}, 60,
                                chains=chains)


def test_chains_are_read_from_bonds():
    layout = ChainLayout((5, 4, 3), (True, False, True))
    assert ChainLayout.from_bonds(12, layout.bonds()) == layout
    assert ChainLayout.from_bonds(12, layout.bonds()[::-1, ::-1]) == layout  # any order
    assert ChainLayout.from_bonds(12, []) is None
    assert ChainLayout.from_bonds(4, [(0, 2), (1, 3)]) is None  # not bead chains in order
    assert ChainLayout.from_bonds(4, [(0, 1), (1, 2)]) is None  # bead 3 bonded to nothing


def test_describe_is_one_short_line_for_any_number_of_chains():
    from knotmm.model.layout import ChainLayout

    assert ChainLayout((90,), (True,)).describe() == "90 beads, one ring"
    assert ChainLayout((60, 30), (True, False)).describe() == (
        "90 beads in 2 chains (A: ring of 60, B: open, 30)")
    many = ChainLayout((60,) * 2 + (3,) * 198, (True,) * 2 + (False,) * 198)
    text = many.describe()
    assert text == "714 beads in 200 chains (2 rings of 60, 198 open of 3)"
    lots = ChainLayout(tuple(range(3, 103)), (False,) * 100)  # 100 lengths: still one line
    assert lots.describe() == "5250 beads in 100 chains (100 open, 3-102 beads each)"
