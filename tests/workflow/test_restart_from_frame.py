"""A new run from a frame of an earlier run of several chains (issue 34, "Files in").

``knotmm run --from RUN`` (or ``[knot] kind = "file"``, ``path = RUN``, ``frame = -1``)
starts a new run, its time from 0, from the last frame of a finished run of a Hopf link. With
a fixed-step method the new run continues the old one: its frames are those of the same run
made 2 tau_d longer, up to the float32 rounding of the frame it starts from and the shift of
the centre of mass to the origin (every template starts centred). Before, such a run could
not be read back ("holds 2 chains", and before that one chain with a 1.33 d bond).
"""

from __future__ import annotations

import numpy as np
import pytest
import reference_model as rm

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.io.dcd import read_dcd
from knotmm.io.rundir import read_facts
from knotmm.workflow import run

T_RESTART = 1.0  # the first run ends here; the longer one goes on to T_RESTART + 2
FRAME = 0.25


def hopf_config(duration: float) -> RunConfig:
    return RunConfig.from_dict({
        "knot": {"kind": "knotinfo", "name": "hopf", "beads": 40},
        "model": {"gravity": 1.0},
        "run": {"duration": duration, "integrator": "heun", "timestep": 0.005,
                "topology_check_interval": 0.0},
        "output": {"frame_interval": FRAME, "checkpoint_interval": 1.0},
    })


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``short``: the link run to T_RESTART; ``long``: the same run 2 tau_d longer."""
    base = tmp_path_factory.mktemp("restart")
    run(hopf_config(T_RESTART), directory=base / "short", progress=False)
    run(hopf_config(T_RESTART + 2.0), directory=base / "long", progress=False)
    return base


def _frames(directory):
    return read_dcd(directory / "trajectory.dcd")[0]


def test_a_new_run_from_the_last_frame_continues_the_run(runs, capsys):
    short, long = runs / "short", runs / "long"
    last = _frames(short)[-1]
    np.testing.assert_array_equal(last, _frames(long)[int(round(T_RESTART / FRAME))])
    new = runs / "new"
    assert main(["run", "--from", str(short), "--out", str(new), "--duration", "0.5",
                 "--no-progress"]) == 0
    frames = _frames(new)
    assert frames.shape[0] == 3  # t = 0, 0.25, 0.5 of the new run
    shift = last.mean(axis=0)  # the start is centred: the old frame's centre of mass
    np.testing.assert_allclose(frames[0] + shift, last, atol=1e-5)
    after = _frames(long)[int(round(T_RESTART / FRAME)) + 1]  # the original's next frame
    # 2.3e-5 d here: the start is the float32 frame, and the CPU platform's single-precision
    # forces round differently at the centred positions (1e-7 of 20 d in a bond of k = 50)
    error = np.abs(frames[1] + shift - after).max()
    assert error < 1e-4, f"the restart's first frame is {error:.2e} d off the run's next"
    facts = read_facts(new)
    assert facts["time_reached"] == pytest.approx(0.5)  # its time counts from 0
    assert facts["layout"]["lengths"] == [20, 20]
    assert facts["layout"]["closed"] == [True, True]
    source = facts["started_from"]
    assert source["run"] == str(short.resolve())
    assert (source["frame"], source["frames"]) == (4, 5)
    assert source["time"] == pytest.approx(T_RESTART)
    lk = rm.gauss_linking(frames[-1][:20], frames[-1][20:])
    assert facts["linking_numbers"] == {"A-B": round(lk)} and abs(abs(lk) - 1) < 0.05
    settings = RunConfig.from_dict({k: v for k, v in _toml(new).items() if k != "knotmm"})
    assert settings["run.integrator"] == "heun" and settings["run.timestep"] == 0.005
    assert settings["knot.kind"] == "file" and settings["knot.frame"] == -1


def test_the_run_file_form_and_other_settings(runs):
    """``[knot] kind = "file"``, ``path = RUN``, ``frame = -1`` in a run file of other
    settings (here a stiffer bend) starts from the same frame."""
    cfg = hopf_config(0.25).replace({"knot.kind": "file", "knot.path": str(runs / "short"),
                                     "knot.frame": -1, "model.bending_stiffness": 20.0})
    out = runs / "stiff"
    run(cfg, directory=out, progress=False)
    last = _frames(runs / "short")[-1]
    np.testing.assert_allclose(_frames(out)[0] + last.mean(axis=0), last, atol=1e-5)
    facts = read_facts(out)
    assert facts["layout"]["lengths"] == [20, 20]
    assert _toml(out)["model"]["bending_stiffness"] == 20.0


@pytest.mark.parametrize(("args", "says"), [
    (["--from", "{short}"], "give --out DIR"),
    (["--from", "{short}", "--out", "{short}"], "is where --from"),
    (["--from", "{short}", "--out", "{tmp}/x", "--beads", "40"], "fixes the beads"),
    (["--frame", "-1", "--out", "{tmp}/x"], "--frame -1 applies only with --from"),
    (["--from", "{tmp}/none", "--out", "{tmp}/x"], "no such run directory or file"),
    (["--from", "{short}", "--out", "{tmp}/x", "--frame", "9"], "knot.frame=9 is out of range"),
])
def test_bad_starts_are_one_line_exit_2(runs, tmp_path, capsys, args, says):
    args = [a.format(short=runs / "short", tmp=tmp_path) for a in args]
    capsys.readouterr()
    assert main(["run", *args, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("knotmm: error: ") and err.count("\n") == 1, err
    assert says in err, err
    assert not (tmp_path / "x").exists()


def _toml(directory):
    from knotmm.config import read_toml

    return read_toml(directory / "run.toml")
