"""Two rings sedimenting one above the other, against the published statements found.

Set-up: two identical flat rings (``kind = "knotinfo"``, ``name = "0_1"``: a circle of N = 30
beads, bond 0.6 d, radius 2.87 d), horizontal and coaxial, the second D0 above the first
(centre to centre), the study's model otherwise (F0 = 1 per bead downwards, RPY mobility,
steric range 0.56 d), no noise. Bending stiffness A per joint sets the elasto-gravitation
number ``B = N^3 F0 l0 / A`` (N beads per ring, l0 the bond length).

Statements compared (README):

1. The rigid-body limit (a theorem of Stokes flow, not a simulation): two identical rigid
   bodies, each symmetric under the mirror z -> -z through its own centre, one exactly above
   the other, fall at the same speed: the mirror through the mid-plane swaps the bodies and
   reverses the forces, and the linearity of Stokes flow turns that into equal vertical
   velocities, so their distance stays constant. Checked here with a rigid-body solve of
   the RPY mobility written in this script, and with stiff rings run by knotmm.
2. Gruca, Bukowicki and Ekiel-Jezewska (Phys. Rev. E 91, 2015; arXiv 1502.03353): two
   regular horizontal polygons of point particles (no bonds, "rings"), centred one above the
   other, "fall together and periodically oscillate". knotmm's rings are bonded (their
   perimeter is held by the bonds), so this is the nearest published case, not the same
   system.

    python examples/two_rings/run_two_rings.py [--out runs/two_rings] [--quick]

writes one run directory per case below ``--out`` and ``results.json`` there, and prints
the table of the README. A finished run directory is not run again.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import knotmm
from knotmm.config import RunConfig

N = 30  #: beads per ring
L0 = 0.6  #: bond length, d
A_BEAD = 0.5  #: bead (hydrodynamic) radius, d
#: the cases: (bending stiffness per joint A in F0 d, bond stiffness k in F0/d); the study's
#: k is 50. B = N^3 l0 / A = 16200 / A.
CASES = {"k50_A5": (5.0, 50.0), "k50_A5000": (5000.0, 50.0), "k500_A5": (5.0, 500.0),
         "k500_A5000": (5000.0, 500.0), "k5000_A5": (5.0, 5000.0),
         "k5000_A5000": (5000.0, 5000.0)}
DISTANCES = (3.0, 6.0, 12.0)  #: D0, centre to centre, d
#: A ring whose normal is more than this off the vertical (degrees) ends the axisymmetric
#: phase (the rings no longer flat, coaxial and horizontal).
TILTED = 5.0


def elasto_gravitation(a: float) -> float:
    """B = N^3 F0 l0 / A (F0 = 1)."""
    return N**3 * L0 / a


def settings(a: float, d0: float, bond_stiffness: float) -> dict:
    """The run file of two flat coaxial rings, the second ``d0`` above the first."""
    ring = {"kind": "knotinfo", "name": "0_1", "beads": N}
    model = {"bending_stiffness": a, "bond_stiffness": bond_stiffness}
    return {"chains": [{**ring, "offset": [0.0, 0.0, 0.0]},
                       {**ring, "offset": [0.0, 0.0, d0]}], "model": model}


def run_case(name: str, cfg: dict, out: Path, duration: float, frame: float) -> Path:
    directory = out / name
    record = directory / "run.toml"
    if record.is_file() and 'status = "finished"' in record.read_text():
        return directory
    config = RunConfig.from_dict({
        **cfg, "run": {"duration": duration, "topology_check_interval": 0.0, "seed": 1},
        "output": {"frame_interval": frame, "checkpoint_interval": 50.0}})
    knotmm.run(config, directory=directory, progress=False, overwrite=True)
    return directory


# -- the rigid-body limit, solved here --------------------------------------------------------
def rpy_mobility(x: np.ndarray, a: float = A_BEAD) -> np.ndarray:
    """The dense RPY mobility of equal beads (radius ``a``), units of 1/(6 pi eta a) = 1,
    shape (3n, 3n); overlapping pairs (r < 2a) by the regularised form."""
    n = len(x)
    m = np.zeros((3 * n, 3 * n))
    eye = np.eye(3)
    for i in range(n):
        m[3 * i:3 * i + 3, 3 * i:3 * i + 3] = eye
        for j in range(i + 1, n):
            r = x[i] - x[j]
            d = float(np.linalg.norm(r))
            rr = np.outer(r, r) / d**2
            if d >= 2 * a:
                block = (3 * a / (4 * d)) * ((1 + 2 * a**2 / (3 * d**2)) * eye
                                             + (1 - 2 * a**2 / d**2) * rr)
            else:
                block = (1 - 9 * d / (32 * a)) * eye + (3 * d / (32 * a)) * rr
            m[3 * i:3 * i + 3, 3 * j:3 * j + 3] = block
            m[3 * j:3 * j + 3, 3 * i:3 * i + 3] = block
    return m


def rigid_ring_speeds(d0: float) -> tuple[float, float]:
    """Sedimentation speeds (d/tau_d, F0 = 1 per bead) of two rigid flat coaxial rings ``d0``
    apart: each ring moves as a rigid body (6 unknowns), its beads' forces sum to N F0 down
    and zero torque. Returns (lower, upper)."""
    t = 2 * np.pi * np.arange(N) / N
    radius = L0 / (2 * np.sin(np.pi / N))
    ring = np.c_[radius * np.cos(t), radius * np.sin(t), np.zeros(N)]
    x = np.vstack([ring, ring + [0.0, 0.0, d0]])
    resistance = np.linalg.inv(rpy_mobility(x))  # bead forces = R . bead velocities
    # bead velocities = K . (U1, W1, U2, W2)
    k = np.zeros((3 * 2 * N, 12))
    for body in range(2):
        centre = x[body * N:(body + 1) * N].mean(axis=0)
        for i in range(body * N, (body + 1) * N):
            r = x[i] - centre
            k[3 * i:3 * i + 3, 6 * body:6 * body + 3] = np.eye(3)
            k[3 * i:3 * i + 3, 6 * body + 3:6 * body + 6] = -np.array(
                [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    grand = k.T @ resistance @ k  # the two bodies' 12 x 12 resistance
    load = np.zeros(12)
    load[2], load[8] = -float(N), -float(N)  # gravity on each body, no torque
    motion = np.linalg.solve(grand, load)
    return -float(motion[2]), -float(motion[8])


# -- measurements -----------------------------------------------------------------------------
def ring_measures(x: np.ndarray) -> dict[str, np.ndarray]:
    """Per frame: centre (T, 3), mean radius about the centre in the ring's own plane, tilt of
    the ring's normal to the vertical (degrees), out-of-plane rms (d)."""
    centre = x.mean(axis=1)
    rel = x - centre[:, None]
    gyration = np.einsum("fni,fnj->fij", rel, rel) / x.shape[1]
    values, vectors = np.linalg.eigh(gyration)
    normal = vectors[:, :, 0]
    tilt = np.degrees(np.arccos(np.clip(np.abs(normal[:, 2]), 0.0, 1.0)))
    return {"centre": centre, "radius": np.linalg.norm(rel, axis=2).mean(axis=1),
            "tilt": tilt, "out_of_plane": np.sqrt(values[:, 0])}


def closest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest bead-bead distance between two rings, per frame, d."""
    return np.linalg.norm(a[:, :, None] - b[:, None, :], axis=-1).min(axis=(1, 2))


def measure(directory: Path) -> dict:
    data = knotmm.load_run(directory)
    t = data.times
    lower, upper = data.positions[:, :N], data.positions[:, N:]
    lo, up = ring_measures(lower), ring_measures(upper)
    dz = up["centre"][:, 2] - lo["centre"][:, 2]
    offset = np.linalg.norm((up["centre"] - lo["centre"])[:, :2], axis=1)
    early = t <= t[0] + 5.0
    passes = t[1:][np.sign(dz[1:]) != np.sign(dz[:-1])]  # one ring through the other
    tilted = np.maximum(lo["tilt"], up["tilt"]) > TILTED
    symmetric_until = float(t[np.argmax(tilted)]) if tilted.any() else None
    end = symmetric_until if symmetric_until is not None else float(t[-1])
    sym_passes = passes[passes <= end]  # passes while both rings stay flat and coaxial
    bound = None
    if len(sym_passes):
        inside = (t >= sym_passes[0]) & (t <= end)
        bound = float(np.abs(dz[inside]).max())
    slope0 = float(np.polyfit(t[early], dz[early], 1)[0])  # the first 5 tau_d
    keep = t >= t[0] + (t[-1] - t[0]) / 2  # the second half
    fit = np.polyval(np.polyfit(t[keep], dz[keep], 1), t[keep])
    return {
        "duration": float(t[-1]),
        "dz_start": float(dz[0]), "dz_end": float(dz[-1]), "dz_min": float(dz.min()),
        "dz_max": float(dz.max()),
        "dz_late_max": float(np.abs(dz[keep]).max()),
        "dz_rate_first_5": slope0,
        "dz_rate_second_half": float(np.polyfit(t[keep], dz[keep], 1)[0]),
        "dz_swing_second_half": float(np.ptp(dz[keep] - fit)),
        "upper_still_above": bool(dz[-1] > 0),
        "passes": len(passes), "pass_times": [float(v) for v in passes],
        "first_pass_time": float(passes[0]) if len(passes) else None,
        "symmetric_until": symmetric_until,
        "passes_symmetric": len(sym_passes),
        "pass_interval_symmetric": (float(np.diff(sym_passes).mean()) if len(sym_passes) > 1
                                    else None),
        "dz_amplitude_after_first_pass": bound,
        "speed_first_5": float(-np.polyfit(t[early], 0.5 * (lo["centre"][early, 2]
                                                          + up["centre"][early, 2]), 1)[0]),
        "radius_rate_first_5": [float(np.polyfit(t[early], m["radius"][early], 1)[0])
                                for m in (lo, up)],
        "tilt_max": [float(lo["tilt"].max()), float(up["tilt"].max())],
        "mean_time_between_passes": (float(np.diff(passes).mean()) if len(passes) > 1
                                     else None),
        "horizontal_offset_end": float(offset[-1]),
        "radius_lower_end": float(lo["radius"][-1]), "radius_upper_end": float(up["radius"][-1]),
        "tilt_end": [float(lo["tilt"][-1]), float(up["tilt"][-1])],
        "out_of_plane_end": [float(lo["out_of_plane"][-1]), float(up["out_of_plane"][-1])],
        "closest_bead_distance": float(closest(lower, upper).min()),
        "speed": float((lo["centre"][0, 2] + up["centre"][0, 2] - lo["centre"][-1, 2]
                        - up["centre"][-1, 2]) / (2 * (t[-1] - t[0]))),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=Path("runs/two_rings"))
    p.add_argument("--quick", action="store_true", help="short runs (a smoke test)")
    args = p.parse_args(argv)
    duration = 20.0 if args.quick else 200.0
    cases = {k: CASES[k] for k in ("k50_A5", "k5000_A5000")} if args.quick else CASES
    distances = (3.0,) if args.quick else DISTANCES
    started = time.perf_counter()
    results: dict = {"N": N, "bond_length": L0, "duration": duration, "rigid_solve": {},
                     "runs": {}}
    print("rigid-body limit (RPY rigid-body solve): speeds of the lower and upper ring")
    for d0 in DISTANCES:
        v_lo, v_up = rigid_ring_speeds(d0)
        results["rigid_solve"][f"D{d0:g}"] = {"lower": v_lo, "upper": v_up,
                                              "difference": v_up - v_lo}
        print(f"  D0 = {d0:4g} d: {v_lo:.6f}  {v_up:.6f}  difference {v_up - v_lo:+.2e}")
    print(f"\n{'case':>12} {'B':>7} {'D0':>4} {'V 0-5':>7} {'dz/dt 0-5':>10} "
          f"{'dR/dt low, up':>17} {'1st pass':>8} {'flat until':>10} {'passes':>6} "
          f"{'interval':>8} {'|dz| bound':>10} {'dz end':>7} {'closest':>7}")
    for label, (a, k) in cases.items():
        for d0 in distances:
            name = f"{label}_D{d0:g}"
            m = measure(run_case(name, settings(a, d0, k), args.out, duration, 0.5))
            m.update(A=a, B=elasto_gravitation(a), D0=d0, bond_stiffness=k,
                     rigid_speed=results["rigid_solve"][f"D{d0:g}"]["lower"])
            results["runs"][name] = m

            def show(v, fmt):
                return "-" if v is None else format(v, fmt)

            print(f"{label:>12} {m['B']:7.3g} {d0:4g} {m['speed_first_5']:7.4f} "
                  f"{m['dz_rate_first_5']:+10.2e} {m['radius_rate_first_5'][0]:+8.1e},"
                  f"{m['radius_rate_first_5'][1]:+8.1e} "
                  f"{show(m['first_pass_time'], '.1f'):>8} "
                  f"{show(m['symmetric_until'], '.1f'):>10} {m['passes_symmetric']:6d} "
                  f"{show(m['pass_interval_symmetric'], '.2f'):>8} "
                  f"{show(m['dz_amplitude_after_first_pass'], '.2f'):>10} "
                  f"{m['dz_end']:7.2f} {m['closest_bead_distance']:7.2f}")
    results["wall_time_s"] = time.perf_counter() - started
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "results.json").write_text(json.dumps(results, indent=1) + "\n")
    print(f"\n{results['wall_time_s']:.0f} s; results in {args.out / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
