"""Movies from a tiny run: GIF always, MP4 when imageio-ffmpeg is installed."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.errors import ConfigError
from knotmm.movie import make_movie, render_frames

HAVE_FFMPEG = importlib.util.find_spec("imageio_ffmpeg") is not None


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from knotmm.workflow import run

    directory = tmp_path_factory.mktemp("movie") / "run"
    cfg = RunConfig.from_dict(
        {"knot": {"beads": 30}, "run": {"duration": 4.0}, "output": {"frame_interval": 0.5}}
    )
    run(cfg, directory=directory, progress=False)
    return directory  # 9 frames: t = 0, 0.5, ..., 4


def test_gif_has_the_expected_frames(tiny_run, tmp_path):
    from PIL import Image

    out = tmp_path / "m.gif"
    result = make_movie(tiny_run, out=out, stride=2, fps=10, dpi=40)
    assert result.format == "gif" and result.frames == 5  # frames 0, 2, 4, 6, 8
    with Image.open(out) as im:
        assert im.n_frames == 5
        assert im.size == (480, 184)
        assert im.info["duration"] == 100


def test_time_window_and_tracer(tiny_run, tmp_path):
    result = make_movie(
        tiny_run, out=tmp_path / "w.gif", t_from=1.0, t_to=3.0, dpi=30, tracer=-1, trail=0
    )
    assert result.frames == 5 and result.stride == 1


def test_fallen_counts_from_the_runs_start_in_a_movie_started_later(tiny_run, tmp_path,
                                                                     monkeypatch):
    """``--from 2``: the label's "fallen" is the centre of mass's drop since t = 0 (read here
    from the DCD with mdtraj), not since the movie's first frame."""
    import mdtraj

    import knotmm.movie

    labels = []
    draw = knotmm.movie._Scene.draw

    def spy(self, rel, history, label):
        labels.append(label)
        return draw(self, rel, history, label)

    monkeypatch.setattr(knotmm.movie._Scene, "draw", spy)
    make_movie(tiny_run, out=tmp_path / "late.gif", t_from=2.0, dpi=30, trail=0)
    traj = mdtraj.load(str(tiny_run / "trajectory.dcd"), top=str(tiny_run / "topology.pdb"))
    z = traj.xyz.mean(axis=1)[:, 2]  # mdtraj's nm: the file's 10 Angstrom per d read as 1
    want = [f"fallen {z[0] - z[k]:.1f} d" for k in range(4, 9)]  # frames at t = 2 ... 4
    assert [lab.split("    ")[1] for lab in labels] == want
    assert z[0] - z[4] > 1.0  # it had fallen before the movie starts


def test_a_default_frame_is_readable_and_its_texts_do_not_overlap():
    """At the default resolution every text is at least 11 px (tick labels of 9 pt at 100
    dpi; they were 6 px) and no two texts overlap, the 3D panel's ticks and labels included."""
    from drawn_text import overlapping_texts, smallest_text_px

    from knotmm.movie import DEFAULT_DPI, _Scene
    from knotmm.shapes import torus_knot

    x = torus_knot(2, 3, 90)
    positions = np.stack([x, x - [0.0, 0.0, 3.0]])
    com = positions.mean(axis=1)
    scene = _Scene(positions, com, 0, 0, DEFAULT_DPI, "T(2,3), N = 90")
    image = scene.draw(positions[1] - com[1], np.zeros((1, 3)), "t = 1.0    fallen 3.0 d")
    assert image.shape == (460, 1200, 3)
    assert smallest_text_px(scene.fig) >= 11.0
    assert overlapping_texts(scene.fig) == []


@pytest.mark.skipif(not HAVE_FFMPEG, reason="imageio-ffmpeg not installed")
def test_mp4_has_the_expected_frames(tiny_run, tmp_path, capsys):
    import imageio_ffmpeg

    assert main(["movie", str(tiny_run), "--fps", "12", "--dpi", "40"]) == 0
    out = tiny_run / "movie.mp4"  # the default file
    assert "MP4, 9 frames" in capsys.readouterr().out
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 9


def test_default_is_gif_without_ffmpeg(tiny_run, monkeypatch, tmp_path):
    import knotmm.movie

    monkeypatch.setattr(knotmm.movie, "mp4_available", lambda: False)
    result = make_movie(tiny_run, stride=4, dpi=30)
    assert result.path == tiny_run / "movie.gif" and result.frames == 3
    with pytest.raises(ConfigError, match=r"MP4 needs imageio-ffmpeg.*knotmm\[movie\]"):
        make_movie(tiny_run, out=tmp_path / "x.mp4")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"fps": 0}, "--fps 0"),
        ({"stride": 0}, "--stride 0"),
        ({"tracer": 30}, "--bead 30: the chain has 30 beads"),
        ({"out": "movie.avi"}, "expected a file ending in .mp4 or .gif"),
        ({"t_from": 100.0}, "no frame in this window"),
    ],
)
def test_bad_options(tiny_run, kwargs, message):
    with pytest.raises(ConfigError, match=message):
        make_movie(tiny_run, **kwargs)


def test_frames_follow_the_centre_of_mass():
    # a rigid ring falling fast: every frame looks the same because the view follows it
    t = np.arange(3) * 1.0
    ring = np.c_[
        3 * np.cos(np.linspace(0, 2 * np.pi, 20, endpoint=False)),
        3 * np.sin(np.linspace(0, 2 * np.pi, 20, endpoint=False)),
        np.zeros(20),
    ]
    positions = np.stack([ring + [0, 0, -50.0 * k] for k in range(3)])
    frames = list(render_frames(positions, t, dpi=30, trail=0))
    assert len(frames) == 3 and frames[0].dtype == np.uint8 and frames[0].shape[2] == 3
    # only the text line (time, distance fallen) differs between frames
    diff = np.any(frames[0] != frames[2], axis=2)
    rows = np.flatnonzero(diff.any(axis=1))
    assert rows.size and rows.max() < 0.15 * frames[0].shape[0]
