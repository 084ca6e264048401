"""Tilt of the torus axis against gravity and flips of the torus in a knotmm run.

Usage: python examples/brownian_pe2/flips.py RUN_DIR [--band DEG] [--min-winding W]

Prints the tilt statistics and every flip (a crossing of 90 degrees by the signed tilt,
with hysteresis, counted only in frames where the chain still circulates about its axis)
and writes ``tilt.csv`` (time, signed tilt, inclination, planar winding) into RUN_DIR.
See :mod:`knotmm.analysis.tilt` for the definitions.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from knotmm.analysis.tilt import tilt_analysis
from knotmm.io.run_data import load_run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="run directory")
    parser.add_argument("--band", type=float, default=30.0, help="hysteresis half-width, deg")
    parser.add_argument(
        "--min-winding",
        type=float,
        default=1.0,
        help="planar winding below which a frame "
        "has no meaningful orientation (a flat T(2,q) torus has ~2)",
    )
    args = parser.parse_args(argv)
    data = load_run(args.run)
    result = tilt_analysis(data.positions, data.times, args.band, args.min_winding)
    out = Path(args.run) / "tilt.csv"
    np.savetxt(
        out,
        np.column_stack([result.times, result.tilt, result.inclination, result.winding]),
        delimiter=",",
        header="time_tau_d,tilt_signed_deg,inclination_deg,planar_winding",
        comments="",
        fmt="%.6g",
    )
    print(f"frames {data.n_frames}, t = {data.times[0]:g} .. {data.times[-1]:g} tau_d")
    step = 20.0
    print(f"{'t [tau_d]':>14} {'winding':>8} {'inclination [deg]':>18}  (medians)")
    for t0 in np.arange(data.times[0], data.times[-1], step):
        sel = (result.times >= t0) & (result.times < t0 + step)
        print(
            f"{t0:6.0f} - {t0 + step:<6.0f} {np.median(result.winding[sel]):8.2f} "
            f"{np.median(result.inclination[sel]):18.1f}"
        )
    summary = result.to_dict()
    print(f"toroidal frames (winding >= {args.min_winding:g}): {summary['fraction_toroidal']:.2f}")
    flips = result.flips
    print(f"flips (band 90 +- {args.band:g} deg, toroidal frames only): {flips.count}")
    for t, d in zip(flips.times, flips.directions, strict=True):
        print(f"  t = {t:8.2f} tau_d  {'up -> down' if d > 0 else 'down -> up'}")
    for note in flips.notes:
        print(f"note: {note}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
