"""Elastic filaments sedimenting alone and in pairs, against three published statements.

1. Bukowicki and Ekiel-Jezewska, Soft Matter 15, 9405 (2019), abstract: two identical elastic
   filaments settling side by side "usually converge toward horizontal and parallel
   orientation"; "once aligned, the two fibres either converge toward a stationary,
   flexibility-dependent distance, or tend to collide or continuously repel each other";
   "rigid and straight rods perform periodic motions while settling down".
2. Gruca, Bukowicki and Ekiel-Jezewska (arXiv 2303.00548), abstract: "two ball-chains,
   initially one above the other, later move away or approach each other, for a larger or
   smaller initial distance, respectively".
3. A single filament bends into a U whose depth grows with the elasto-gravitation number; for
   small deflections linear elasticity gives a depth proportional to B (the beam under a
   uniform load, its drag the load's opposite).

Each case is run with knotmm (open chains of N = 20 beads, ``[[chains]]`` files written here,
the study's model otherwise: bond 0.6 d, steric range 0.56 d, F0 = 1 per bead, RPY
mobility), and measured from the saved trajectories with :func:`knotmm.load_run`. The
elasto-gravitation number used throughout is

    B = N^3 F0 l0 / A,

N beads per filament, l0 the bond length, A the bending stiffness per joint (the study's
discrete bending); B = 0.12 N^3 at the study's A = 5.

    python examples/filament_pairs/run_pairs.py [--out runs/filament_pairs] [--quick]

writes the runs below ``--out`` and ``results.json`` there, and prints the tables of the
README. Nothing is re-run when a run directory is complete (delete it to run it again).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

import knotmm
from knotmm.config import RunConfig

N = 20  #: beads per filament
L0 = 0.6  #: bond length, d
#: bending stiffness per joint (F0 d) -> B = N^3 l0 / A = 4800 / A
STIFFNESS = {"flexible": 5.0, "medium": 50.0, "stiff": 500.0, "rigid": 5000.0}


def elasto_gravitation(a: float, n: int = N) -> float:
    """B = N^3 F0 l0 / A (F0 = 1)."""
    return n**3 * L0 / a


def _axis_angle(matrix: np.ndarray) -> list[float]:
    """[x, y, z, degrees] of a rotation matrix (the run file's ``rotation``)."""
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(matrix) - 1) / 2))))
    if angle < 1e-9:
        return [0.0, 0.0, 1.0, 0.0]
    axis = np.array([matrix[2, 1] - matrix[1, 2], matrix[0, 2] - matrix[2, 0],
                     matrix[1, 0] - matrix[0, 1]])
    return [*map(float, axis / np.linalg.norm(axis)), angle]


def _turn(axis: str, degrees: float) -> np.ndarray:
    """The right-handed rotation by ``degrees`` about a coordinate axis (as the run file's
    ``rotation``)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c  # e_i -> c e_i + s e_j
    return m


def _chain(offset, matrix=None) -> dict:
    entry = {"kind": "straight", "closed": False, "beads": N, "offset": list(offset)}
    if matrix is not None:
        entry["rotation"] = _axis_angle(matrix)
    return entry


def side_by_side(a: float, distance: float, yaw: float = 10.0, tilt: float = 10.0) -> dict:
    """Two rods along x, their centres ``distance`` apart along y, mirror images of each other
    in the vertical plane y = 0: each turned by +-``yaw`` about z (not parallel) and tilted by
    ``tilt`` about y (not horizontal)."""
    first = _turn("y", tilt) @ _turn("z", yaw)
    mirror = np.diag([1.0, -1.0, 1.0])
    second = mirror @ first @ mirror  # the mirror image's rotation (a proper rotation)
    return {"chains": [_chain([0.0, -distance / 2, 0.0], first),
                       _chain([0.0, distance / 2, 0.0], second)],
            "model": {"bending_stiffness": a}}


def one_above_the_other(a: float, distance: float) -> dict:
    """Two horizontal rods along x, parallel, the second ``distance`` above the first."""
    return {"chains": [_chain([0.0, 0.0, 0.0]), _chain([0.0, 0.0, distance])],
            "model": {"bending_stiffness": a}}


def single(a: float) -> dict:
    return {"chains": [_chain([0.0, 0.0, 0.0])], "model": {"bending_stiffness": a}}


def run_case(name: str, settings: dict, out: Path, duration: float, frame: float) -> Path:
    directory = out / name
    record = directory / "run.toml"
    if record.is_file() and 'status = "finished"' in record.read_text():
        return directory
    cfg = RunConfig.from_dict({
        **settings,
        "run": {"duration": duration, "topology_check_interval": 0.0, "seed": 1},
        "output": {"frame_interval": frame, "checkpoint_interval": 50.0},
    })
    knotmm.run(cfg, directory=directory, progress=False, overwrite=True)
    return directory


# -- measurements -------------------------------------------------------------------------------
def _ends(x: np.ndarray) -> np.ndarray:
    """End-to-end vector of each frame, shape (T, 3)."""
    return x[:, -1] - x[:, 0]


def inclination(x: np.ndarray) -> np.ndarray:
    """Angle of the end-to-end vector to the horizontal plane, degrees, shape (T,)."""
    e = _ends(x)
    return np.degrees(np.arctan2(np.abs(e[:, 2]), np.linalg.norm(e[:, :2], axis=1)))


def relative_yaw(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between the horizontal projections of two chains' end-to-end vectors, 0-90 deg."""
    u, v = _ends(a)[:, :2], _ends(b)[:, :2]
    cos = np.abs(np.sum(u * v, axis=1)) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
    return np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))


def depth(x: np.ndarray) -> np.ndarray:
    """How far the middle bead hangs below the ends' mean height (the U's depth), d, (T,)."""
    return 0.5 * (x[:, 0, 2] + x[:, -1, 2]) - x[:, N // 2, 2]


def closest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest bead-bead distance between two chains, per frame, d."""
    return np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))


def trend(t: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of ``y`` over the last third of the run, per tau_d."""
    keep = t >= t[0] + 2 * (t[-1] - t[0]) / 3
    return float(np.polyfit(t[keep], y[keep], 1)[0])


def swing(t: np.ndarray, y: np.ndarray) -> float:
    """Peak-to-peak of ``y`` over the last third of the run, after removing its linear trend."""
    keep = t >= t[0] + 2 * (t[-1] - t[0]) / 3
    fit = np.polyval(np.polyfit(t[keep], y[keep], 1), t[keep])
    return float(np.ptp(y[keep] - fit))


def measure_pair(directory: Path, vertical: bool) -> dict:
    data = knotmm.load_run(directory)
    a, b = data.positions[:, :N], data.positions[:, N:]
    t = data.times
    ca, cb = a.mean(axis=1), b.mean(axis=1)
    # side by side: the horizontal distance; one above the other: the whole distance
    gap = np.linalg.norm(cb - ca if vertical else (cb - ca)[:, :2], axis=1)
    near = closest(a, b)
    out = {
        "duration": float(t[-1]),
        "distance_start": float(gap[0]), "distance_end": float(gap[-1]),
        "distance_min": float(gap.min()), "distance_trend": trend(t, gap),
        "distance_swing": swing(t, gap),
        "closest_bead_distance": float(near.min()),
        "closest_bead_distance_end": float(near[-1]),
        "inclination_range_last_half": [float(np.ptp(inclination(a)[len(t) // 2:])),
                                        float(np.ptp(inclination(b)[len(t) // 2:]))],
        "inclination_end": [float(inclination(a)[-1]), float(inclination(b)[-1])],
        "relative_yaw_start": float(relative_yaw(a, b)[0]),
        "relative_yaw_end": float(relative_yaw(a, b)[-1]),
        "depth_end": [float(depth(a)[-1]), float(depth(b)[-1])],
        "speed": float((ca[0, 2] + cb[0, 2] - ca[-1, 2] - cb[-1, 2]) / (2 * (t[-1] - t[0]))),
    }
    if vertical:  # which chain is above at the end, and how far apart horizontally
        out["upper_is_still_above"] = bool(cb[-1, 2] > ca[-1, 2])
        out["horizontal_offset_end"] = float(np.linalg.norm((cb - ca)[-1, :2]))
    return out


#: Beads of two chains closer than this (d) are in contact: the steric range, 2^(1/6) 0.5 d.
CONTACT = 2 ** (1 / 6) * 0.5


def verdict_pair(m: dict, tolerance: float = 0.02) -> str:
    """What the distance did in the last third of the run: "in contact" (beads of the two
    chains inside the steric range at the end), else "stationary" (it changed by less than
    ``tolerance`` of itself), "approach" or "separate"; ", touched" when beads met earlier."""
    if m["closest_bead_distance_end"] < CONTACT:
        return "in contact"
    rate = m["distance_trend"] * m["duration"] / 3 / m["distance_end"]
    word = "stationary" if abs(rate) < tolerance else ("approach" if rate < 0 else "separate")
    return word + (", touched" if m["closest_bead_distance"] < CONTACT else "")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=Path("runs/filament_pairs"))
    p.add_argument("--quick", action="store_true", help="short runs (a smoke test)")
    args = p.parse_args(argv)
    duration, frame = (20.0, 1.0) if args.quick else (400.0, 1.0)
    stiff = {"flexible": 5.0, "rigid": 5000.0} if args.quick else STIFFNESS
    distances = [3.0] if args.quick else [3.0, 5.0, 8.0]
    started = time.perf_counter()
    results: dict = {"N": N, "bond_length": L0, "duration": duration, "single": {},
                     "side_by_side": {}, "one_above_the_other": {}}

    print(f"single filament, N = {N}: the U's depth at t = {duration:g} tau_d")
    print(f"{'A':>8} {'B':>8} {'depth [d]':>10} {'depth/B':>10} {'speed':>8}")
    for label, a in stiff.items():
        data = knotmm.load_run(run_case(f"single_{label}", single(a), args.out, duration, frame))
        x = data.positions
        d_end = float(depth(x)[-1])
        speed = float((x[0, :, 2].mean() - x[-1, :, 2].mean()) / data.times[-1])
        b = elasto_gravitation(a)
        results["single"][label] = {"A": a, "B": b, "depth": d_end, "speed": speed,
                                    "inclination": float(inclination(x)[-1])}
        print(f"{a:8g} {b:8.3g} {d_end:10.4f} {d_end / b:10.3g} {speed:8.4f}")

    above = [3.0] if args.quick else [3.0, 8.0, 16.0, 32.0]
    for kind, build, vertical, gaps in (("side_by_side", side_by_side, False, distances),
                                        ("one_above_the_other", one_above_the_other, True,
                                         above)):
        print(f"\n{kind.replace('_', ' ')}: distance between centres "
              f"({'3D' if vertical else 'horizontal'}), orientations at the end")
        print(f"{'A':>8} {'B':>8} {'D0':>5} {'D end':>7} {'min':>6} {'trend':>9} "
              f"{'swing':>7} {'closest':>8} {'incl.':>11} {'yaw':>11}  verdict")
        for label, a in stiff.items():
            for d0 in gaps:
                name = f"{kind}_{label}_D{d0:g}"
                m = measure_pair(run_case(name, build(a, d0), args.out, duration, frame),
                                 vertical)
                m.update(A=a, B=elasto_gravitation(a), D0=d0, verdict=verdict_pair(m))
                results[kind][name] = m
                print(f"{a:8g} {m['B']:8.3g} {d0:5g} {m['distance_end']:7.2f} "
                      f"{m['distance_min']:6.2f} {m['distance_trend']:+9.4f} "
                      f"{m['distance_swing']:7.3f} {m['closest_bead_distance']:8.2f} "
                      f"{max(m['inclination_end']):5.1f} deg "
                      f"{m['relative_yaw_start']:4.0f}->{m['relative_yaw_end']:4.1f}  "
                      f"{m['verdict']}")
    results["wall_time_s"] = time.perf_counter() - started
    (args.out / "results.json").write_text(json.dumps(results, indent=1) + "\n")
    print(f"\n{results['wall_time_s']:.0f} s; results in {args.out / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
