"""``knotmm movie``: render a run as an MP4 (with imageio-ffmpeg) or GIF movie."""

from __future__ import annotations

import argparse

from knotmm.movie import DEFAULT_DPI

__all__ = ["add_parser", "execute"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``knotmm movie``."""
    p = subparsers.add_parser(
        "movie",
        help="render a run as a movie (3D, side and top views following the knot)",
        description=(
            "Render a run directory as a movie: a 3D view with gravity down, a side view and "
            "a top view, centred on the centre of mass as it falls, one bead in red with a "
            "trail so the swirl is visible. MP4 when imageio-ffmpeg is installed "
            "(knotmm[movie]), else GIF. The movie is written to a temporary file and renamed "
            "when complete; an unwritable --out is refused before rendering (exit 2), a "
            "failure while writing (a full disk) is one line and exit 3."
        ),
    )
    p.add_argument("run", metavar="RUN_DIR", help="run directory")
    p.add_argument(
        "--out",
        metavar="FILE",
        help="movie file, .mp4 or .gif (default: RUN_DIR/movie.mp4, or .gif "
        "without imageio-ffmpeg)",
    )
    p.add_argument("--fps", type=float, default=20.0, help="frames per second (default 20)")
    p.add_argument(
        "--stride",
        type=int,
        metavar="K",
        help="use every K-th trajectory frame (default: 1, or more to keep the "
        "movie under 600 frames)",
    )
    p.add_argument(
        "--bead", type=int, default=0, metavar="I", help="the bead drawn in red (default 0)"
    )
    p.add_argument(
        "--trail",
        type=int,
        default=30,
        metavar="K",
        help="movie frames in the red bead's trail (default 30; 0: none)",
    )
    p.add_argument("--from", dest="t_from", type=float, metavar="T", help="start at time T (tau_d)")
    p.add_argument("--to", dest="t_to", type=float, metavar="T", help="end at time T (tau_d)")
    p.add_argument(
        "--dpi",
        type=float,
        default=DEFAULT_DPI,
        help=f"resolution, up to 600; the frame is 12 x 4.6 inches (default {DEFAULT_DPI:g})",
    )
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None,
                     help="always show the progress bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false",
                     help="never show the progress bar (default: a bar on a terminal, else "
                     "a line every 10 %%)")
    p.set_defaults(execute=execute)
    return p


def execute(args) -> int:
    """Render and print the one-line summary (exit 130 with one line when stopped)."""
    try:
        return _execute(args)
    except KeyboardInterrupt:  # Ctrl-C; SIGTERM too (knotmm.cli.main)
        import sys

        out = args.out or "the movie"
        print(f"knotmm: interrupted: {out} was not written (the movie goes to a temporary "
              f"file until complete; a file of that name before is left as it was)",
              file=sys.stderr)
        return 130


def _execute(args) -> int:
    from knotmm.movie import make_movie

    result = make_movie(
        args.run,
        out=args.out,
        fps=args.fps,
        stride=args.stride,
        tracer=args.bead,
        trail=args.trail,
        t_from=args.t_from,
        t_to=args.t_to,
        dpi=args.dpi,
        progress=args.progress,
    )
    print(result.summary())
    return 0
