"""Sweep files: expansion, seeds, validation, naming, summary and plots (no simulation)."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.errors import ConfigError
from knotmm.sweep import (
    ANALYSIS_COLUMNS,
    Sweep,
    expand,
    load_sweep_file,
    point_name,
    read_summary,
    replica_seeds,
    summary_values,
)
from knotmm.sweep.summary import summary_text


def sweep_dict(**sweep):
    return {
        "knot": {"beads": 40},
        "run": {"duration": 10.0},
        "output": {"directory": "sweeps/test"},
        "sweep": sweep,
    }


# -- expansion -------------------------------------------------------------------------------
def test_grid_is_full_product_last_key_fastest():
    points = expand({"a": [1, 2, 3], "b": ["x", "y"]})
    assert len(points) == 6
    assert points[:3] == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 2, "b": "x"}]
    assert {(p["a"], p["b"]) for p in points} == {(a, b) for a in (1, 2, 3) for b in "xy"}


def test_zip_pairs_values_and_checks_lengths():
    assert expand({"a": [1, 2], "b": [3, 4]}, "zip") == [{"a": 1, "b": 3}, {"a": 2, "b": 4}]
    with pytest.raises(ConfigError, match="equal length: a has 2, b has 3"):
        expand({"a": [1, 2], "b": [3, 4, 5]}, "zip")
    with pytest.raises(ConfigError, match="mode"):
        expand({"a": [1]}, "cartesian")


def test_sweep_grid_and_zip_points():
    grid = Sweep.from_dict(
        sweep_dict(**{"knot.beads": [40, 50], "model.bending_stiffness": [1, 5.0]})
    )
    assert [p.name for p in grid.points] == [
        "knot.beads=40,model.bending_stiffness=1",
        "knot.beads=40,model.bending_stiffness=5.0",
        "knot.beads=50,model.bending_stiffness=1",
        "knot.beads=50,model.bending_stiffness=5.0",
    ]
    last = grid.points[-1].config
    assert last["knot.beads"] == 50 and last["model.bending_stiffness"] == 5.0
    assert last["run.duration"] == 10.0  # base values kept
    assert last["output.directory"].endswith(
        "sweeps/test/knot.beads=50,model.bending_stiffness=5.0"
    )
    zipped = Sweep.from_dict(sweep_dict(mode="zip", **{"knot.p": [3, 2], "knot.q": [2, 5]}))
    assert [p.values for p in zipped.points] == [
        {"knot.p": 3, "knot.q": 2},
        {"knot.p": 2, "knot.q": 5},
    ]
    assert zipped.x_key == "point"


def test_nested_table_form_equals_quoted_keys():
    quoted = Sweep.from_dict(sweep_dict(**{"knot.beads": [40, 60]}))
    nested = Sweep.from_dict(sweep_dict(knot={"beads": [40, 60]}))
    assert [p.config for p in quoted.points] == [p.config for p in nested.points]
    assert nested.keys == ("knot.beads",)


# -- seeds ---------------------------------------------------------------------------------
def test_replica_seeds_follow_seedsequence_spawn():
    seeds = replica_seeds(1234, 4)
    children = np.random.SeedSequence(1234).spawn(4)
    assert seeds == [int(c.generate_state(1, dtype=np.uint32)[0]) for c in children]
    assert replica_seeds(1234, 4) == seeds  # reproducible
    assert replica_seeds(1234, 6)[:4] == seeds  # adding replicas keeps the first ones
    assert len(set(seeds)) == 4
    assert replica_seeds(1235, 4) != seeds


def test_ensemble_points_get_derived_seeds():
    sweep = Sweep.from_dict(
        sweep_dict(seeds=3, seed=7, **{"knot.beads": [40, 50], "knot.perturbation": [0.01]})
    )
    assert len(sweep.points) == 6
    expected = replica_seeds(7, 3)
    assert [p.config["run.seed"] for p in sweep.points] == expected * 2
    assert sweep.points[1].name == "knot.beads=40,knot.perturbation=0.01,replica=1"
    assert sweep.points[1].replica == 1
    assert sweep.columns == ("knot.beads", "knot.perturbation", "replica", "run.seed")
    assert not sweep.notes
    # default base seed: run.seed of the file
    data = sweep_dict(seeds=2, **{"knot.beads": [40]})
    data["run"]["seed"] = 11
    deterministic = Sweep.from_dict(data)
    assert [p.config["run.seed"] for p in deterministic.points] == replica_seeds(11, 2)
    assert "identical" in deterministic.notes[0]


# -- validation ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("sweep", "message"),
    [
        ({"knot.bead": [40]}, "unknown key \\[knot\\] bead; did you mean 'beads'"),
        ({"kont.beads": [40]}, "unknown key 'kont.beads'"),
        ({"knot.beads": 40}, "knot.beads = 40: expected a list"),
        ({"knot.beads": []}, "the list is empty"),
        ({"knot.beads": [40, 40]}, "lists 40 twice"),
        ({"knot.beads": [40, "many"]}, "point knot.beads=many: knot.beads = 'many'"),
        ({"model.bond_stiffness": [50.0, -1.0]}, "point model.bond_stiffness=-1.0: .*must be > 0"),
        ({"output.directory": ["a", "b"]}, "output.directory cannot be swept"),
        ({"mod": "grid", "knot.beads": [40]}, "unknown \\[sweep\\] option 'mod'.*'mode'"),
        ({"mode": "product", "knot.beads": [40]}, "mode = 'product'"),
        ({"seeds": 0, "knot.beads": [40]}, "seeds = 0: expected an integer >= 1"),
        ({"seeds": 2, "run.seed": [1, 2]}, "use one of the two"),
        ({}, "lists no keys"),
        ({"x": "knot.p", "knot.beads": [40]}, "x = 'knot.p'"),
    ],
)
def test_bad_sweep_tables_raise_one_line(sweep, message):
    with pytest.raises(ConfigError, match=message) as info:
        Sweep.from_dict(sweep_dict(**sweep))
    assert "\n" not in str(info.value)


def test_missing_sweep_table_and_bad_base():
    with pytest.raises(ConfigError, match="no \\[sweep\\] table"):
        Sweep.from_dict({"knot": {"beads": 40}})
    with pytest.raises(ConfigError, match="unknown key \\[run\\] duraton"):
        Sweep.from_dict({"run": {"duraton": 4.0}, "sweep": {"knot.beads": [40]}})


def test_directory_defaults_and_override(tmp_path):
    path = tmp_path / "fig.toml"
    path.write_text('[sweep]\n"knot.beads" = [40]\n')
    assert str(load_sweep_file(path).directory) == "sweeps/fig"
    assert load_sweep_file(path, directory=tmp_path / "o").directory == tmp_path / "o"
    assert str(Sweep.from_dict({"sweep": {"knot.beads": [40]}}).directory) == "sweeps/sweep"


def test_point_names_are_readable_and_stable():
    assert point_name({"knot.beads": 40}) == "knot.beads=40"
    assert point_name({"model.bending_stiffness": 0.001}) == "model.bending_stiffness=0.001"
    assert (
        point_name({"knot.mirror": True, "knot.word": [1, -2]}) == "knot.mirror=true,knot.word=1_-2"
    )
    assert point_name({"knot.name": "5/2 x"}) == "knot.name=5_2_x"
    assert point_name({}, replica=2) == "replica=2"


# -- command line ------------------------------------------------------------------------------
def test_cli_bad_key_exits_2_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sweep_out"
    path = tmp_path / "bad.toml"
    path.write_text(f'[output]\ndirectory = "{out}"\n[sweep]\n"knot.beds" = [40, 50]\n')
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[sweep] unknown key [knot] beds; did you mean 'beads'" in err[0]
    assert not out.exists()


def test_cli_one_bad_point_stops_everything_before_writing(tmp_path, capsys):
    out = tmp_path / "sweep_out"
    path = tmp_path / "bad.toml"
    path.write_text(f'[output]\ndirectory = "{out}"\n[sweep]\n"run.duration" = [5.0, -1.0]\n')
    assert main(["sweep", str(path)]) == 2
    assert "point run.duration=-1.0" in capsys.readouterr().err
    assert not out.exists()


def test_cli_dry_run_lists_points(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\n"knot.beads" = [40, 50]\n"knot.mirror" = [false, true]\n')
    assert main(["sweep", str(path), "--dry-run", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "4 points" in out and "knot.beads=50,knot.mirror=true" in out
    assert not (tmp_path / "o").exists()


# -- summary and plots ---------------------------------------------------------------------------
def fake_rows(sweep):
    rows = []
    for i, p in enumerate(sweep.points):
        values = summary_values(
            {
                "tau_swirl_over_tau_sed": 10.0 + i,
                "tau_swirl_over_tau_sed_uncertainty": 0.1,
                "tau_rot_over_tau_sed": 200.0 + 3 * i,
                "major_radius": 4.0 + 0.1 * i,
                "major_radius_geometric": 4.2,
                "swirl_amplitude": 0.3,
                "sedimentation_velocity": 11.0,
                "rotation_sense": "clockwise",
                "knot_type_start": "3_1",
                "knot_type_end": "+12n655",
                "knot_type_changed_at": 473.0,
                "knot_type_changes": [{"time": 473.0, "from": "3_1", "to": "+12n655"}],
                "window": [3.5, 20.0],
                "fit_quality": {"r2": 0.9},
                "average_crossing_number": 4.5,
                "radius_of_gyration": 3.25,
                "radius_of_gyration_perp": 3.0,
                "torus_fraction": 0.5,
                "torus_fraction_window": 1.0,
                "uncertainties": {"average_crossing_number": {"std_error": 0.25},
                                  "radius_of_gyration": {"std_error": None}},
            }
        )
        rows.append(
            {
                "point": p.name,
                "directory": p.name,
                **p.values,
                "replica": p.replica,
                "status": "finished",
                "error": None,
                **values,
            }
        )
    return rows


def test_summary_roundtrip(tmp_path):
    sweep = Sweep.from_dict(sweep_dict(**{"knot.beads": [40, 50]}))
    rows = fake_rows(sweep)
    rows[1].update(status="error", error="TemplateError: too few, really", **summary_values(None))
    (tmp_path / "summary.csv").write_text(summary_text(sweep.columns, rows))
    back = read_summary(tmp_path)
    header = (tmp_path / "summary.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["point", "directory", "knot.beads", "status", "error"]
    assert header[5:] == list(ANALYSIS_COLUMNS)
    assert back[0]["knot.beads"] == 40 and back[0]["tau_swirl_over_tau_sed"] == 10.0
    assert back[0]["window_start"] == 3.5 and back[0]["fit_r2"] == 0.9
    assert back[0]["rotation_sense"] == "clockwise"
    assert back[0]["knot_type_start"] == "3_1" and back[0]["knot_type_end"] == "+12n655"
    assert back[0]["knot_type_changed_at"] == 473.0 and back[0]["p"] is None
    assert back[0]["knot_type_change_count"] == 1
    assert back[0]["average_crossing_number"] == 4.5
    assert back[0]["average_crossing_number_uncertainty"] == 0.25
    assert back[0]["radius_of_gyration"] == 3.25
    assert back[0]["radius_of_gyration_uncertainty"] is None
    assert back[0]["radius_of_gyration_perp"] == 3.0 and back[0]["asphericity"] is None
    assert back[0]["torus_fraction"] == 0.5 and back[0]["torus_fraction_window"] == 1.0
    assert back[1]["knot_type_change_count"] is None and back[1]["torus_fraction"] is None
    assert back[1]["error"] == "TemplateError: too few, really" and back[1]["tau_sed"] is None


@pytest.mark.parametrize(
    "sweep",
    [
        {"knot.beads": [40, 50, 60]},
        {"model.bending_stiffness": [0.05, 0.5, 5.0, 50.0], "knot.mirror": [False, True]},
        {"mode": "zip", "knot.p": [3, 2], "knot.q": [2, 5]},
        {"seeds": 3, "knot.beads": [40, 50], "knot.perturbation": [0.01]},
    ],
)
def test_sweep_plots_are_written(tmp_path, sweep):
    import matplotlib

    matplotlib.use("Agg")
    from knotmm.sweep.plots import save_sweep_plots

    s = Sweep.from_dict(sweep_dict(**sweep))
    paths = save_sweep_plots(
        fake_rows(s),
        tmp_path,
        s.x_key,
        s.keys,
        group_by=[] if s.options.mode == "zip" else list(s.keys),
    )
    assert [p.name for p in paths] == ["ratios.png", "shape.png"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_no_plot_without_finished_points(tmp_path):
    from knotmm.sweep.plots import save_sweep_plots

    s = Sweep.from_dict(sweep_dict(**{"knot.beads": [40]}))
    rows = fake_rows(s)
    rows[0]["status"] = "fault"
    assert save_sweep_plots(rows, tmp_path, s.x_key, s.keys) == []


def test_base_config_is_a_valid_run_config():
    s = Sweep.from_dict(sweep_dict(**{"knot.beads": [40]}))
    assert isinstance(s.base, RunConfig)
    again = Sweep.from_dict({k: v for k, v in __import__("tomllib").loads(s.to_toml()).items()})
    assert [p.config["knot.beads"] for p in again.points] == [40]


def test_points_that_are_not_periodic_are_flagged():
    from knotmm.sweep.plots import _poor

    clean = {
        "fit_r2": 0.97,
        "knot_type_changed_at": 473.0,
        "window_start": 36.5,
        "window_end": 351.5,
    }
    assert not _poor(clean)
    assert _poor({**clean, "fit_r2": 0.3})
    assert _poor({**clean, "knot_type_changed_at": 300.0})  # strand passage inside the window
    assert _poor({**clean, "knot_type_changed_at": 20.0})  # ... or before it
    assert not _poor({"fit_r2": None})


def test_run_toml_as_base_lets_the_radius_follow_the_beads():
    data = {
        "knot": {"beads": 90, "major_radius": 4.2},
        "output": {"directory": "x"},
        "knotmm": {"status": "finished"},  # a run's run.toml
        "sweep": {"knot.beads": [40, 60]},
    }
    sweep = Sweep.from_dict(data)
    assert [p.config["knot.major_radius"] for p in sweep.points] == [None, None]
    assert "major_radius" in sweep.notes[0]
    plain = Sweep.from_dict({k: v for k, v in data.items() if k != "knotmm"})
    assert [p.config["knot.major_radius"] for p in plain.points] == [4.2, 4.2]


def test_cli_dry_run_reports_points_that_run_would_refuse(tmp_path, capsys):
    """`sweep --dry-run` refuses per point exactly what `knotmm run` refuses (issue 11 item 8)."""
    run_file = tmp_path / "r.toml"
    run_file.write_text("[knot]\nbeads = 20\n")
    assert main(["run", str(run_file), "--out", str(tmp_path / "run")]) == 2
    refusal = capsys.readouterr().err.strip()
    assert refusal.startswith("knotmm: error: ") and "knot.beads=20" in refusal
    assert not (tmp_path / "run").exists()

    out = tmp_path / "o"
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\n"knot.beads" = [20, 30]\n')
    assert main(["sweep", str(path), "--dry-run", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    message = refusal.removeprefix("knotmm: error: ")
    assert captured.err.strip().splitlines() == [f"knotmm: error: point knot.beads=20: {message}"]
    listing = captured.out.splitlines()
    assert listing[1].endswith("knot.beads=20  cannot run")
    assert listing[2].endswith("knot.beads=30")
    assert "1 of 2 points cannot run" in captured.out
    assert not out.exists()


def test_cli_dry_run_checks_the_integrator_per_point(tmp_path, capsys):
    """A deterministic integrator at a finite Peclet number: `run` refuses it, so does the
    dry run, for that point only."""
    run_file = tmp_path / "r.toml"
    run_file.write_text('[knot]\nbeads = 40\n[run]\nintegrator = "rk23"\npeclet = 50.0\n')
    assert main(["run", str(run_file), "--out", str(tmp_path / "run")]) == 2
    message = capsys.readouterr().err.strip().removeprefix("knotmm: error: ")
    path = tmp_path / "s.toml"
    path.write_text(
        '[knot]\nbeads = 40\n[run]\nintegrator = "rk23"\n'
        '[sweep]\n"run.peclet" = [inf, 50.0]\n'
    )
    assert main(["sweep", str(path), "--dry-run", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"knotmm: error: point run.peclet=50.0: {message}"]
