"""Movies of a run: a 3D view, a side view and a top view, following the centre of mass.

Each frame is drawn with matplotlib's Agg canvas (no display needed) in three panels:

* a 3D view (gravity points down the vertical axis),
* a side view (x horizontal, z up),
* a top view (seen from above, x to the right, y up),

all centred on the chain's centre of mass, so the camera falls with the knot; the distance
fallen and the time are written on the frame. Beads are drawn as discs of half a bead
diameter (the model's beads overlap, l0 = 0.6 d: full-size discs would hide the strands),
each chain as a line (a ring closed, an open chain not; one colour per chain when there
are several), and one *tracer* bead in a distinct colour with a short trail
of its recent positions (relative to the centre of mass), which makes the swirl visible.

The frames are encoded as MP4 (H.264) when the optional extra ``imageio-ffmpeg`` is
installed, else as an animated GIF (Pillow, a matplotlib dependency), into a temporary file
beside the movie that is renamed once complete.

Examples
--------
>>> from knotmm.movie import make_movie
>>> make_movie("runs/trefoil", fps=20)                           # doctest: +SKIP
MovieResult(path=PosixPath('runs/trefoil/movie.mp4'), frames=401, ...)
"""

from __future__ import annotations

import importlib.util
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm.errors import ConfigError, KnotmmError
from knotmm.io.atomic import replacing
from knotmm.io.rundir import check_output_file, writing_output
from knotmm.limits import MAX_DPI
from knotmm.progress import Progress

__all__ = [
    "MovieResult", "make_movie", "render_frames", "still", "mp4_available", "MAX_AUTO_FRAMES",
]

log = logging.getLogger(__name__)

#: With ``stride=None`` the stride is chosen so that a movie has at most this many frames.
MAX_AUTO_FRAMES = 600

_BEAD = "#4a7fb5"
_LINE = "#2b4a6b"
_TRACER = "#d62728"


def mp4_available() -> bool:
    """Whether MP4 output is possible (the optional extra ``imageio-ffmpeg`` is installed)."""
    return importlib.util.find_spec("imageio_ffmpeg") is not None


@dataclass
class MovieResult:
    """A movie written by :func:`make_movie`.

    Attributes
    ----------
    path : Path
    frames : int
        Frames in the movie.
    fps : float
        Frames per second.
    format : {"mp4", "gif"}
    stride : int
        Trajectory frames per movie frame.
    """

    path: Path
    frames: int
    fps: float
    format: str
    stride: int

    def summary(self) -> str:
        """The one-line summary the CLI prints."""
        seconds = self.frames / self.fps
        return (
            f"wrote {self.path} ({self.format.upper()}, {self.frames} frames, stride "
            f"{self.stride}, {self.fps:g} fps, {seconds:.1f} s)"
        )


def _format_for(out: Path | None) -> str:
    if out is None:
        return "mp4" if mp4_available() else "gif"
    suffix = out.suffix.lower()
    if suffix == ".gif":
        return "gif"
    if suffix == ".mp4":
        if not mp4_available():
            raise ConfigError(
                f"--out {out}: MP4 needs imageio-ffmpeg (pip install 'knotmm[movie]'); "
                f"or write a GIF: --out {out.with_suffix('.gif')}"
            )
        return "mp4"
    raise ConfigError(f"--out {out}: expected a file ending in .mp4 or .gif")


#: Default resolution of a movie frame (12 x 4.6 inches: 1200 x 460 pixels): its fonts (tick
#: labels 9 pt, 12 px) readable on a projector.
DEFAULT_DPI = 100.0


class _Scene:
    """The three panels of one figure and the artists updated frame by frame."""

    def __init__(
        self,
        positions: np.ndarray,
        com: np.ndarray,
        tracer: int,
        trail: int,
        dpi: float,
        title: str,
        layout=None,
    ):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.ticker import MaxNLocator

        from knotmm.analysis.drawing import bead_colors

        self.tracer = tracer
        self.trail = trail
        n = positions.shape[1]
        # the chains drawn: one ring of all the beads unless a layout says otherwise
        self.chains = ([(slice(0, n), True)] if layout is None else
                       list(zip(layout.slices(), layout.closed, strict=True)))
        several = len(self.chains) > 1  # then one colour per chain, as view.vmd
        colors = bead_colors(layout, n) if several else None
        rel = positions - com[:, None, :]
        half = float(np.max(np.abs(rel))) + 0.8  # every frame fits, plus a bead's margin
        self.half = half
        self.fig = Figure(figsize=(12.0, 4.6), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        self.fig.subplots_adjust(left=0.03, right=0.98, bottom=0.12, top=0.84, wspace=0.32)
        ax3 = self.fig.add_subplot(1, 3, 1, projection="3d")
        side = self.fig.add_subplot(1, 3, 2)
        top = self.fig.add_subplot(1, 3, 3)
        self.fig.suptitle(title, fontsize=13)
        self.text = self.fig.text(0.5, 0.895, "", ha="center", fontsize=11)

        for ax in (ax3,):
            ax.set_xlim(-half, half)
            ax.set_ylim(-half, half)
            ax.set_zlim(-half, half)
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev=22, azim=-60)
            for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # few ticks: labels apart
                axis.set_major_locator(MaxNLocator(3, symmetric=True))
            ax.set_xlabel("x [d]", fontsize=10, labelpad=2)
            ax.set_ylabel("y [d]", fontsize=10, labelpad=2)
            ax.set_zlabel("z [d]", fontsize=10, labelpad=2)
            ax.tick_params(labelsize=8, pad=0)
            ax.set_title("3D (gravity down)", fontsize=11)
        for ax, name, labels in (
            (side, "side view (x, z)", ("x [d]", "z [d]")),
            (top, "top view (x, y), from above", ("x [d]", "y [d]")),
        ):
            ax.set_xlim(-half, half)
            ax.set_ylim(-half, half)
            ax.set_aspect("equal")
            ax.set_title(name, fontsize=11)
            ax.set_xlabel(labels[0], fontsize=10)
            ax.set_ylabel(labels[1], fontsize=10)
            ax.tick_params(labelsize=9)
            ax.grid(True, alpha=0.25)
        # gravity arrow beside the side view (outside it: never over the chain)
        side.annotate(
            "",
            xy=(1.05, 0.2),
            xytext=(1.05, 0.5),
            xycoords="axes fraction",
            arrowprops={"arrowstyle": "-|>", "color": "0.3", "lw": 1.5},
            annotation_clip=False,
        )
        side.text(
            1.08,
            0.35,
            "g",
            transform=side.transAxes,
            ha="left",
            va="center",
            color="0.3",
            fontsize=12,
            style="italic",
        )
        self.canvas.draw()
        # marker size: one bead diameter in points, from the side panel's scale
        bbox = side.get_window_extent()
        points_per_d = bbox.width / (2 * half) * 72.0 / dpi
        ms = max(2.0, 0.55 * points_per_d)  # half a diameter: the overlapping beads stay apart
        ms3 = ms * 0.8

        self.lines, self.beads, self.tracers, self.trails = [], [], [], []
        self.ax3, self.side, self.top = ax3, side, top
        self._artists3, self._artists2 = [], [[], []]
        for sl, _ in self.chains:
            line_c, bead_c = (colors[sl.start], colors[sl.start]) if several else (_LINE, _BEAD)
            (l3,) = ax3.plot([], [], [], "-", color=line_c, lw=1.0, alpha=0.7)
            (b3,) = ax3.plot([], [], [], "o", ms=ms3, color=bead_c, mec="none", alpha=0.85)
            self._artists3.append((l3, b3))
            for k, ax in enumerate((side, top)):
                (line,) = ax.plot([], [], "-", color=line_c, lw=1.0, alpha=0.7, zorder=2)
                (beads,) = ax.plot([], [], "o", ms=ms, color=bead_c, mec="none", alpha=0.75,
                                   zorder=3)
                self._artists2[k].append((line, beads))
        (r3,) = ax3.plot([], [], [], "-", color=_TRACER, lw=1.0, alpha=0.6)
        (t3,) = ax3.plot([], [], [], "o", ms=ms3 * 1.15, color=_TRACER, mec="k", mew=0.5)
        self._tracer3 = (r3, t3)
        self._tracer2 = []
        for ax in (side, top):
            (trail_line,) = ax.plot([], [], "-", color=_TRACER, lw=1.2, alpha=0.6, zorder=4)
            (tr,) = ax.plot([], [], "o", ms=ms * 1.15, color=_TRACER, mec="k", mew=0.6, zorder=5)
            self._tracer2.append((trail_line, tr))

    def draw(self, rel: np.ndarray, history: np.ndarray, label: str) -> np.ndarray:
        """Draw one frame; ``rel`` (n_beads, 3) and ``history`` (k, 3) relative to the COM.

        Returns the RGB image, shape (height, width, 3), uint8.
        """
        paths = [np.vstack([rel[sl], rel[sl][:1]]) if ring else rel[sl]
                 for sl, ring in self.chains]  # a ring closes; an open chain does not
        r3, t3 = self._tracer3
        for (l3, b3), path, (sl, _) in zip(self._artists3, paths, self.chains, strict=True):
            l3.set_data_3d(path[:, 0], path[:, 1], path[:, 2])
            b3.set_data_3d(rel[sl, 0], rel[sl, 1], rel[sl, 2])
        r3.set_data_3d(history[:, 0], history[:, 1], history[:, 2])
        tb = rel[self.tracer]
        t3.set_data_3d([tb[0]], [tb[1]], [tb[2]])
        for artists, (trail_line, tr), (i, j) in zip(
            self._artists2, self._tracer2, ((0, 2), (0, 1)), strict=True
        ):
            for (line, beads), path, (sl, _) in zip(artists, paths, self.chains, strict=True):
                line.set_data(path[:, i], path[:, j])
                beads.set_data(rel[sl, i], rel[sl, j])
            trail_line.set_data(history[:, i], history[:, j])
            tr.set_data([tb[i]], [tb[j]])
        self.text.set_text(label)
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()


def _pad16(image: np.ndarray) -> np.ndarray:
    """Pad an RGB image with white to a multiple of 16 pixels each way (H.264 blocks)."""
    h, w = image.shape[:2]
    ph, pw = (-h) % 16, (-w) % 16
    if ph or pw:
        image = np.pad(image, ((0, ph), (0, pw), (0, 0)), constant_values=255)
    return image


def render_frames(
    positions: np.ndarray,
    times: np.ndarray,
    tracer: int = 0,
    trail: int = 30,
    dpi: float = DEFAULT_DPI,
    title: str = "",
    layout=None,
    start_height: float | None = None,
):
    """Yield the movie's RGB frames for a trajectory (all frames given are drawn).

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3), in d
        Gravity along -z.
    times : ndarray, shape (n_frames,), in tau_d
    tracer : int
        Index of the bead drawn in a distinct colour.
    trail : int
        Number of previous frames in the tracer's trail (relative to the centre of mass).
    dpi : float
        Resolution: the frame is 12 x 4.6 inches.
    title : str
    layout : knotmm.model.layout.ChainLayout, optional
        The chains: only their bonds are drawn (none between chains, none across an open
        chain's ends), a colour per chain when there are several. Default: one ring.
    start_height : float, optional
        Height (z, in d) of the centre of mass from which "fallen" is counted: the run's
        start, when the frames given begin later (``--from``). Default: the first frame's.

    Yields
    ------
    ndarray, shape (height, width, 3), uint8
    """
    positions = np.asarray(positions, dtype=np.float64)
    com = positions.mean(axis=1)
    rel = positions - com[:, None, :]
    scene = _Scene(positions, com, tracer, trail, dpi, title, layout)
    z0 = com[0, 2] if start_height is None else float(start_height)
    for k in range(len(positions)):
        history = rel[max(0, k - trail) : k + 1, tracer]
        label = (
            f"t = {times[k]:.1f} $\\tau_d$    fallen {z0 - com[k, 2]:.1f} d    "
            f"(view follows the centre of mass; red: bead {tracer})"
        )
        yield scene.draw(rel[k], history, label)


def make_movie(
    run_dir,
    out=None,
    fps: float = 20.0,
    stride: int | None = None,
    tracer: int = 0,
    trail: int = 30,
    t_from: float | None = None,
    t_to: float | None = None,
    dpi: float = DEFAULT_DPI,
    progress: bool | None = None,
) -> MovieResult:
    """Render a run's trajectory as a movie (MP4 with imageio-ffmpeg, else GIF).

    Parameters
    ----------
    run_dir : path
        A run directory (or a DCD with its PDB; see :func:`knotmm.analysis.load_run`).
    out : path, optional
        The movie file, ``.mp4`` or ``.gif``; default ``RUN_DIR/movie.mp4`` when
        imageio-ffmpeg is installed, else ``RUN_DIR/movie.gif``.
    fps : float
        Frames per second of the movie.
    stride : int, optional
        Use every stride-th trajectory frame; default: 1, or larger so that the movie has at
        most :data:`MAX_AUTO_FRAMES` frames.
    tracer : int
        The bead drawn in a distinct colour (negative counts from the end).
    trail : int
        Movie frames of the tracer's trail.
    t_from, t_to : float, optional
        Time window of the trajectory to show, in tau_d.
    dpi : float
        Resolution (the frame is 12 x 4.6 inches: 1200 x 460 pixels at the default 100 dpi), at most
        :data:`knotmm.limits.MAX_DPI` (600).
    progress : bool, optional
        True: a bar of the frames drawn; False: nothing; None (default): a bar when stderr
        is a terminal, else a line each time another 10 % is drawn
        (:class:`knotmm.progress.Progress`).

    Returns
    -------
    MovieResult

    Raises
    ------
    ConfigError
        A bad option (named), or ``.mp4`` without imageio-ffmpeg.
    TrajectoryFileError
        The run cannot be read.
    knotmm.io.rundir.OutputError
        ``out`` cannot be written (read-only, a directory in the way): exit code 2, before
        any frame is drawn; :class:`~knotmm.io.rundir.WriteFault` (exit code 3) when writing
        fails (a full disk). The movie is written to a temporary name and renamed once
        complete: never a truncated movie under ``out``.
    """
    from knotmm.analysis import load_run
    from knotmm.analysis.drawing import run_layout

    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ConfigError(f"--fps {fps!r}: expected a positive number")
    if stride is not None and (isinstance(stride, bool) or int(stride) != stride or stride < 1):
        raise ConfigError(f"--stride {stride!r}: expected an integer >= 1")
    if int(trail) != trail or trail < 0:
        raise ConfigError(f"--trail {trail!r}: expected an integer >= 0")
    if not (isinstance(dpi, (int, float)) and 0 < dpi <= MAX_DPI):  # also NaN
        raise ConfigError(
            f"--dpi {dpi!r}: expected a number in (0, {MAX_DPI:g}]: the 12 x 4.6 inch frame is "
            f"then at most {12 * MAX_DPI:.0f} x {4.6 * MAX_DPI:.0f} pixels, within H.264's "
            "largest frame (8192 x 4320), and one frame takes at most about 80 MB to draw"
        )
    out = Path(out) if out is not None else None
    fmt = _format_for(out)
    data = load_run(run_dir)
    times, positions = data.times, data.positions
    n = data.n_beads
    if not -n <= tracer < n:
        raise ConfigError(f"--bead {tracer}: the chain has {n} beads (0 .. {n - 1})")
    tracer = tracer % n
    sel = np.ones(len(times), dtype=bool)
    if t_from is not None:
        sel &= times >= t_from - 1e-9
    if t_to is not None:
        sel &= times <= t_to + 1e-9
    if not sel.any():
        raise ConfigError(
            f"--from {t_from} --to {t_to}: no frame in this window (the run has frames from "
            f"{times[0]:g} to {times[-1]:g} tau_d)"
        )
    idx = np.flatnonzero(sel)
    if stride is None:
        stride = max(1, math.ceil(len(idx) / MAX_AUTO_FRAMES))
    idx = idx[:: int(stride)]
    if out is None:
        base = data.directory if data.directory is not None else Path(".")
        out = Path(base) / f"movie.{fmt}"
    check_output_file(out)  # read-only, a directory in the way: one line before rendering

    # "fallen" counts from the run's first frame, also for a movie that starts later
    frames = render_frames(positions[idx], times[idx], tracer, int(trail), dpi, _title(data),
                           run_layout(data), start_height=positions[0].mean(axis=0)[2])
    write = _write_mp4 if fmt == "mp4" else _write_gif
    kept = f"{str(out)!r} was not written (a file of that name before is left as it was)"
    # the movie goes to a temporary name beside `out` and is renamed when complete, so a
    # full disk or a stop never leaves a truncated movie under the final name
    try:
        with Progress(len(idx), "movie", "frames", enabled=progress) as shown, \
                writing_output(out, kept=kept), replacing(out) as tmp, \
                writing_output(out, kept=kept):
            count = write(tmp, _counted(_drawn(frames), shown), fps)
    except _DrawingFailed as exc:  # not a write failure: drawing a frame went wrong
        raise exc.original from None
    log.info("wrote %s (%d frames)", out, count)
    return MovieResult(path=out, frames=count, fps=float(fps), format=fmt, stride=int(stride))


class _DrawingFailed(KnotmmError):
    """Carries an error raised while a frame was drawn past the writers' error handling."""

    def __init__(self, original: BaseException):
        super().__init__(str(original))
        self.original = original


def _counted(frames, shown):
    """The frames, each counted on ``shown`` (a :class:`~knotmm.progress.Progress`)."""
    for frame in frames:
        yield frame
        shown.update(1)


def _drawn(frames):
    """The frames, an error while drawing one wrapped in :class:`_DrawingFailed`."""
    it = iter(frames)
    while True:
        try:
            frame = next(it)
        except StopIteration:
            return
        except KnotmmError:
            raise
        except Exception as exc:  # noqa: BLE001 - re-raised as it was by make_movie
            raise _DrawingFailed(exc) from exc
        yield frame


def _title(data) -> str:
    """The system the movie shows (:func:`knotmm.analysis.drawing.system_title`)."""
    from knotmm.analysis.drawing import system_title

    return system_title(data)


def still(data, frame: int = 0, tracer: int = 0, dpi: float = DEFAULT_DPI):
    """One frame of a run's movie as a matplotlib Figure (what :func:`make_movie` draws).

    Parameters
    ----------
    data : knotmm.io.run_data.RunData
        A loaded run (:func:`knotmm.analysis.load_run`).
    frame : int
        The trajectory frame.
    tracer : int
        The bead drawn in a distinct colour.
    dpi : float

    Returns
    -------
    matplotlib.figure.Figure
    """
    from knotmm.analysis.drawing import run_layout

    positions = np.asarray(data.positions, dtype=np.float64)
    com = positions.mean(axis=1)
    scene = _Scene(positions, com, tracer, 0, dpi, _title(data), run_layout(data))
    rel = positions[frame] - com[frame]
    scene.draw(rel, rel[tracer][None, :], f"t = {data.times[frame]:.1f} $\\tau_d$")
    return scene.fig


def _write_mp4(path: Path, frames, fps: float) -> int:
    import imageio_ffmpeg

    writer = None
    count = 0
    try:
        for frame in frames:
            frame = _pad16(frame)
            if writer is None:
                h, w = frame.shape[:2]
                writer = imageio_ffmpeg.write_frames(
                    str(path),
                    (w, h),
                    fps=fps,
                    codec="libx264",
                    pix_fmt_in="rgb24",
                    pix_fmt_out="yuv420p",
                    quality=7,
                    macro_block_size=16,
                    ffmpeg_log_level="quiet",  # its failures are ours to report, in one line
                )
                writer.send(None)
            writer.send(np.ascontiguousarray(frame).tobytes())
            count += 1
    finally:
        if writer is not None:
            writer.close()
    if count and not _mp4_complete(path):
        # ffmpeg ends quietly when its output fails at the end (a full disk while it writes
        # the trailer): the file is then cut short
        raise RuntimeError("ffmpeg wrote an incomplete MP4 (its index, the moov box, is "
                           "missing or cut short)")
    return count


def _mp4_complete(path) -> bool:
    """Whether an MP4's top-level boxes fill the file exactly and include ``moov``/``mdat``."""
    size = Path(path).stat().st_size
    seen, pos = set(), 0
    with open(path, "rb") as fh:
        while pos < size:
            fh.seek(pos)
            head = fh.read(16)
            if len(head) < 8:
                return False
            n = int.from_bytes(head[:4], "big")
            if n == 1:  # a 64-bit size follows the type
                n = int.from_bytes(head[8:16], "big") if len(head) == 16 else 0
            elif n == 0:  # the box runs to the end of the file
                n = size - pos
            if n < 8:
                return False
            seen.add(head[4:8])
            pos += n
    return pos == size and {b"moov", b"mdat"} <= seen


def _write_gif(path: Path, frames, fps: float) -> int:
    from PIL import Image

    images = [
        Image.fromarray(f).quantize(colors=128, method=Image.Quantize.MEDIANCUT) for f in frames
    ]
    if not images:
        raise ConfigError("no frames to write")
    duration = max(20, int(round(1000.0 / fps)))  # GIF delays are in 10 ms units
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=duration,
        loop=0,
        optimize=False,
        disposal=1,
    )
    return len(images)
