"""Property-based run files: every file either runs or fails with one clear line, exit 2.

Values are drawn around and across the valid ranges (wrong types included); runs are kept
short (duration at most 1 tau_d, at most 120 beads).
"""

import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from knotmm.cli.main import main
from knotmm.config import SCHEMA

anything = st.one_of(
    st.integers(-5, 200),
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.booleans(),
    st.text(max_size=6),
    st.lists(st.integers(-3, 3), max_size=5),
)


def _value(table, key):
    kind = SCHEMA[table][key].kind
    good = {
        "int": st.integers(-2, 130),
        "float": st.floats(-1.0, 3.0, allow_nan=False),
        "bool": st.booleans(),
        "str": st.sampled_from(list(SCHEMA[table][key].choices or ("x",))),
        "int_list": st.lists(st.integers(-3, 3), max_size=6),
    }[kind]
    return st.one_of(good, good, anything)


keys = [(t, k) for t in SCHEMA for k in SCHEMA[t]
        if (t, k) not in {("output", "directory"), ("knot", "path"), ("knot", "topology")}]


@st.composite
def run_files(draw):
    data = {}
    for table, key in draw(st.lists(st.sampled_from(keys), max_size=5, unique=True)):
        data.setdefault(table, {})[key] = draw(_value(table, key))
    if draw(st.booleans()):
        data.setdefault(draw(st.sampled_from(["knot", "run", "bogus"])), {})["typo_key"] = 1
    run = data.setdefault("run", {})
    if not isinstance(run.get("duration"), float) or not 0 < run["duration"] <= 1.0:
        run["duration"] = 0.5
    knot = data.setdefault("knot", {})
    if not isinstance(knot.get("beads"), int) or knot["beads"] > 120:
        knot["beads"] = 40
    out = data.setdefault("output", {})
    out.pop("frame_interval", None)
    out["frame_interval"] = 0.25
    return data


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=run_files())
def test_run_files_run_or_fail_clearly(tmp_path_factory, capsys, data):
    base = tmp_path_factory.mktemp("fuzz")
    path = base / "run.toml"
    try:
        path.write_text(tomli_w.dumps(data))
    except (TypeError, ValueError):
        return  # not expressible in TOML (e.g. NaN inside lists): nothing to test
    code = main(["run", str(path), "--out", str(base / "out"), "--no-progress"])
    captured = capsys.readouterr()
    assert code in (0, 2, 3), code
    if code != 0:
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1, captured.err
        assert lines[0].startswith("knotmm: error: ")
        assert "Traceback" not in captured.err
        if code == 2:
            assert not (base / "out").exists()  # nothing written for bad input
