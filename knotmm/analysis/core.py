"""The analysis pipeline: window -> regime -> observables -> spectra -> fit -> topology -> files.

Every run gets the knot type it recorded, the sedimentation speed and the shape measures of
:mod:`knotmm.analysis.shape` (Rg, its part perpendicular to gravity, asphericity, ACN,
writhe: window means with block-bootstrap errors, series in ``analysis_shape.csv``). The
torus formulas (p, q, ``N l0 / (2 pi p)``) and the vortex-knot fit are made only for a torus
knot (:func:`knotmm.analysis.knot_types.run_knot`) in a flat-torus window, with a note
otherwise.

The regime checks (:mod:`knotmm.analysis.regimes`) sit between the steady window and the
measurements: is there a swirl at all, is the window a flat torus, is it tilted, has the
swirl amplitude relaxed. The vortex-knot fit is made in the body frame
(:func:`knotmm.analysis.regime_report.body_fit_coordinates`). Times are frame index x
frame_interval (mdtraj reads a DCD's time as the frame index).
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np

from knotmm.analysis.fit import fit_vortex_knot
from knotmm.analysis.geometry import cylindrical, winding_numbers
from knotmm.analysis.knot_types import (
    KnotTypes,
    describe_changes,
    handedness,
    knot_types,
    rotation_sense,
    run_knot,
)
from knotmm.analysis.objects import (
    END_TO_END_KEYS,
    RING,
    analyze_open_chain,
    bond_length_of,
    elasto_keys,
    fall_speed,
)
from knotmm.analysis.regime_report import (
    body_fit_coordinates,
    regime_keys,
    shared_knot_cache,
    single_threaded_blas,
)
from knotmm.analysis.regimes import assess
from knotmm.analysis.result import AnalysisResult
from knotmm.analysis.shape import SHAPE_FILE, chains_of, shape_series
from knotmm.analysis.spectra import check_time_scale, rotation_spectrum, swirl_spectrum
from knotmm.analysis.window import MIN_FRAMES, rotation_unmeasured, steady_window
from knotmm.errors import ConfigError
from knotmm.io.atomic import write_text_atomic
from knotmm.io.run_data import RunData, load_run
from knotmm.io.rundir import (
    ANALYSIS_FILE,
    ANALYSIS_RUNNING_KEY,
    LOCK_FILE,
    lock_owner,
    writing,
)

__all__ = ["analyze", "analyze_run", "ANALYSIS_FILE"]

logger = logging.getLogger(__name__)

def _check_int(value, name: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or int(value) != value or int(value) < 1:
        raise ConfigError(f"{name} {value!r}: expected a positive integer")
    return int(value)


def _detected(windings: np.ndarray) -> int | None:
    value = int(round(abs(float(np.median(windings)))))
    return value if value >= 1 else None


@single_threaded_blas
def analyze(
    data: RunData,
    t_from: float | None = None,
    t_to: float | None = None,
    p: int | None = None,
    q: int | None = None,
    knot_samples: int = 40,
    fit: bool = True,
) -> AnalysisResult:
    """Measure every observable of the study on a loaded trajectory (nothing is written).

    Parameters
    ----------
    data : RunData
        From :func:`load_run` (or :meth:`RunData.from_arrays`).
    t_from, t_to : float, optional
        Window start / end in tau_d, replacing the detected ones (see
        :func:`knotmm.analysis.window.steady_window`).
    p, q : int, optional
        The torus knot T(p, q) used in the formulas (giving p makes the run a torus knot).
        Default: ``knot.p``/``knot.q`` of a torus-knot run file, or the (p, q) of a torus
        knot's name or type (p the pair's member the chain winds about the vertical axis);
        with no run file, p is the chain's winding number about the vertical axis and q is
        None (the fit then uses the detected core winding). Any other knot or a link that
        is no torus link gets no p, q, ``N l0 / (2 pi p)`` or fit (a note says why); a torus
        link takes them from its run file; an open chain has none of them, nor a knot type
        (:mod:`knotmm.analysis.objects`), and refuses ``p``/``q``, as a run of several
        chains does.
    knot_samples : int
        Frames identified with topoly when looking for a change of knot type (plus a
        bisection); 0 skips knot identification.
    fit : bool
        False skips the vortex-knot fit.

    Returns
    -------
    AnalysisResult
    """
    p = _check_int(p, "--p")
    q = _check_int(q, "--q")
    if len(data.times) > 1:  # a time axis double precision cannot resolve: refused first
        check_time_scale(float(data.frame_interval),
                         float(data.times[-1] - data.times[0] + data.frame_interval))
    chains = chains_of(data)
    if len(chains) > 1:  # each chain as a run of its own, and the system (analysis.chains)
        from knotmm.analysis.chains import analyze_system

        if p is not None or q is not None:
            raise ConfigError(
                f"--p/--q apply to one ring; this run has {len(chains)} chains, each analysed "
                "with its own knot (a torus link takes its p and q from its run file)")
        return analyze_system(data, chains, _analyze_one, t_from=t_from, t_to=t_to,
                              knot_samples=knot_samples, fit=fit)
    return _analyze_one(data, t_from=t_from, t_to=t_to, p=p, q=q, knot_samples=knot_samples,
                        fit=fit)


def _analyze_one(data: RunData, t_from=None, t_to=None, p=None, q=None, knot_samples=40,
                 fit=True, part_of: str | None = None) -> AnalysisResult:
    """:func:`analyze` of one chain (or of a whole system, for its shape and speed).

    ``part_of`` names the system a chain belongs to (then no note advises ``--p``/``--q``,
    which apply to a run of one ring only). An open chain is measured as what it is
    (:func:`knotmm.analysis.objects.analyze_open_chain`).
    """
    chains = chains_of(data)
    if len(chains) == 1 and not chains[0][1]:
        return analyze_open_chain(data, chains, t_from=t_from, t_to=t_to, p=p, q=q)
    notes = list(data.notes)
    times, positions = data.times, data.positions
    # A change of knot type (strands passing through each other) ends any periodic state:
    # unless --to is given, the window is looked for only in the frames before the first
    # change (the same detection, on a shorter trajectory, so a collapse is still found).
    n_usable = len(times)
    identify = shared_knot_cache()  # both scans below identify mostly the same frames
    if t_to is None and knot_samples > 0 and len(times) > 2:
        scan = knot_types(
            times, positions, 0, len(times) - 1, samples=knot_samples, identify=identify
        )
        first = scan.changes[0] if scan.changes else None
        later = describe_changes(scan.changes[1:])
        later = f"; later {later}" if later else ""
        if first is not None and first["frame"] >= MIN_FRAMES:
            n_usable = int(first["frame"])
            notes.append(
                f"the knot type changed at t = {first['time']:g} tau_d "
                f"({first['from']} -> {first['to']}): the window ends before it{later}"
            )
        elif first is not None:
            # too early for a window before it: the whole-run measures still stand
            notes.append(
                f"the knot type changed at t = {first['time']:g} tau_d "
                f"({first['from']} -> {first['to']}), before the {MIN_FRAMES} frames a window "
                f"needs: the window is looked for in the whole run and may include the "
                f"change{later}"
            )
    window = steady_window(times[:n_usable], positions[:n_usable], t_from=t_from, t_to=t_to)
    # body frame: swirl detection, relaxation, torus shape and tilt (knotmm.analysis.regimes)
    driven = data.get("model.gravity") is None or float(data.get("model.gravity")) != 0.0
    regime = assess(times, positions, window, n_usable, driven=driven)
    window = regime.window
    detected = regime.detection.detected
    notes += window.notes + regime.notes
    sel = window.frames
    t_w, x_w = times[sel], positions[sel]
    coords = cylindrical(positions)
    rho, alpha, z_rel = coords.rho[sel], coords.alpha[sel], coords.z[sel]

    # the knot, and p and q of a torus knot
    if knot_samples > 0:
        kt = knot_types(
            times, positions, window.start, window.stop, samples=knot_samples, identify=identify
        )
    else:
        kt = KnotTypes(None, None, None, notes=["knot identification skipped"])
    knot = run_knot(data, chains, kt.initial)
    axis_w, core_w = winding_numbers(x_w[:: max(1, len(x_w) // 50)],
                                     [sl for sl, _ in chains] if len(chains) > 1 else None)
    p_det, q_det = _detected(axis_w), _detected(core_w)
    torus = knot.torus if p is None else (p, q)
    p, q, p_src, q_src = _torus_pq(torus, knot.torus_source, p, q, p_det, notes)
    if torus is None:
        named = f"{knot.description}" + (
            f", {knot.knot_type} from {knot.source}" if knot.knot_type else "")
        advice = (" (give --p and --q to apply the torus formulas anyway)"
                  if part_of is None and len(chains) == 1 else "")
        notes.append(
            f"not a torus knot ({named}): p, q, N l0/(2 pi p) and the vortex-knot fit are "
            f"not reported{advice}"
        )
    else:
        if p_det is not None and p_det != p:
            notes.append(f"p = {p} ({p_src}) but the chain winds {p_det} times around the axis")
        if q is not None and q_det is not None and q_det != q:
            notes.append(f"q = {q} ({q_src}) but the chain winds {q_det} times around its core")

    # V, rho0, geometric estimate
    velocity, velocity_err = fall_speed(t_w, coords.com[sel, 2])
    radius_per_frame = rho.mean(axis=1)
    rho0, rho0_std = float(radius_per_frame.mean()), float(radius_per_frame.std())
    bond = bond_length_of(data, notes)
    rho_geo = float("nan")
    if torus is not None and regime.toroidal:
        rho_geo = data.n_beads * bond / (2.0 * math.pi * p)
    elif torus is not None:
        notes.append("the window is not a flat torus: N l0/(2 pi p) is not compared with rho0")
    shape = shape_series(times, positions, chains, window.frames)

    # spectra
    swirl = swirl_spectrum(t_w, rho, z_rel)
    rot = rotation_spectrum(t_w, alpha)
    # the same about the torus axis (body frame): the fit's starting values
    body_swirl = swirl_spectrum(t_w, regime.body.rho[sel], regime.body.z[sel])
    body_rot = rotation_spectrum(t_w, regime.body.phi[sel])
    lab_ok = detected and not regime.tilted  # the lab-frame swirl is the swirl
    period_ok = lab_ok  # and its period is measured in this window
    length = t_w[-1] - t_w[0] + data.frame_interval
    if not detected:
        notes.append(regime.detection.reason + ": tau_swirl and C are not reported")
    elif lab_ok and swirl.peak.period > length / 2:
        # the strongest lab-frame line sits at the band's slow edge: the foot of something
        # slower (a wobble of the torus axis), not the swirl the body frame detected
        period_ok = False
        notes.append(
            f"the lab-frame swirl spectrum peaks at the slow edge of its band "
            f"({swirl.peak.period:.4g} tau_d, more than half the {length:g} tau_d window; the "
            f"body frame's line: {body_swirl.peak.period:.4g} tau_d): tau_swirl not measured"
        )
    # tau_rot only where the window holds enough of a turn (as tau_swirl above)
    rot_why = rotation_unmeasured(rot.peak.period, rot.peak.period_uncertainty, length)
    rot_ok = not regime.tilted and rot_why is None
    if rot_why is not None and not regime.tilted:
        notes.append(f"{rot_why}: tau_rot and tau_rot/tau_sed not measured")
    elif rot_ok and rot.peak.period > length:
        notes.append(
            f"the window ({length:g} tau_d) covers {length / rot.peak.period:.0%} of a "
            f"rotation (tau_rot = {rot.peak.period:.4g} tau_d): tau_rot assumes the rotation "
            "is steady"
        )

    # fit
    vfit = None
    q_fit = q if q is not None else q_det
    amplitude = float(np.sqrt(2.0 * np.mean((rho - rho.mean(axis=0)) ** 2)))
    if fit and torus is None:
        fit = False
    if fit and not (detected and regime.toroidal):
        fit = False
        notes.append("no swirl or no flat torus in the window: vortex-knot fit skipped")
    if fit and q_fit is None:
        notes.append("no q given and no core winding detected: vortex-knot fit skipped")
    elif fit:
        if q is None:
            notes.append(f"q not known: the fit uses the detected core winding q = {q_fit}")
        f_rot = body_rot.peak.frequency
        tau_rot_guess = 1.0 / f_rot if f_rot else math.inf
        try:
            vfit = fit_vortex_knot(
                t_w,
                *body_fit_coordinates(regime.body, sel),
                p,
                q_fit,
                body_swirl.peak.period,
                tau_rot_guess,
            )
        except (ValueError, np.linalg.LinAlgError) as exc:
            notes.append(f"vortex-knot fit failed ({exc}); C is the rms swirl of rho")
        if vfit is not None:
            amplitude = vfit.swirl_amplitude
            for name, spec, fitted in (
                ("tau_swirl", body_swirl.peak.period, vfit.tau_swirl),
                ("tau_rot", body_rot.peak.period, abs(vfit.tau_rot)),
            ):
                if abs(spec - fitted) > 0.05 * spec:
                    notes.append(
                        f"{name}: spectrum {spec:.4g} and fit {fitted:.4g} differ "
                        "by more than 5%: the motion is not a clean vortex knot"
                    )
            if vfit.r2.get("total", 0) < 0.5:
                notes.append(
                    f"the vortex-knot formula explains only "
                    f"{vfit.r2['total']:.0%} of the oscillation"
                )

    # topology
    wr, wr_std = shape.value("writhe"), shape.stats["writhe"]["std"]
    notes += kt.notes + _recorded_changes_note(data, kt)

    # tilt of the torus axis against gravity and flips, over the whole trajectory
    from knotmm.analysis.tilt import tilt_analysis

    tilt = tilt_analysis(positions, times).to_dict() if len(times) >= 2 else None
    extra = regime_keys(regime, vfit, p, q_fit, notes, body_swirl, body_rot)
    extra["uncertainties"].update({
        name: {k: v for k, v in stats.items() if k != "std"}
        for name, stats in shape.stats.items()
    })
    if not (detected and regime.toroidal):
        amplitude = float("nan")
    body_why = rotation_unmeasured(
        body_rot.peak.period, body_rot.peak.period_uncertainty, length)
    if body_why is not None:  # the body frame's tau_rot under the same rule
        for key in ("tau_rot_body", "tau_rot_body_uncertainty", "rotation_frequency_body"):
            extra[key] = float("nan")
        if "tau_rot_body" in extra["uncertainties"]:
            extra["uncertainties"]["tau_rot_body"] = {"value": None, "std_error": None}
        if rot_ok or regime.tilted:
            notes.append(f"body frame: {body_why}: tau_rot_body not measured")

    extra.update(elasto_keys(data, data.n_beads, notes))
    result = AnalysisResult(
        sedimentation_velocity=velocity,
        sedimentation_velocity_uncertainty=velocity_err,
        major_radius=rho0,
        major_radius_std=rho0_std,
        major_radius_geometric=rho_geo,
        swirl_amplitude=amplitude,
        tau_swirl=swirl.peak.period if period_ok else float("nan"),
        tau_swirl_uncertainty=swirl.peak.period_uncertainty if period_ok else float("nan"),
        tau_rot=rot.peak.period if rot_ok else float("nan"),
        tau_rot_uncertainty=rot.peak.period_uncertainty if rot_ok else float("nan"),
        rotation_frequency=rot.peak.frequency if rot_why is None else float("nan"),
        rotation_sense=rotation_sense(rot.peak.frequency)
        if regime.toroidal and not regime.tilted
        else None,
        writhe=wr,
        writhe_std=wr_std,
        handedness=handedness(wr),
        window=window,
        p=p,
        q=q,
        p_detected=p_det,
        q_detected=q_det,
        p_source=p_src,
        q_source=q_src,
        bond_length=bond,
        swirl_spectrum=swirl,
        rotation_spectrum=rot,
        fit=vfit,
        knots=kt,
        notes=notes,
        tilt=tilt,
        swirl_detected=lab_ok,
        extra=extra,
        data=data,
        coords=coords,
        knot=knot,
        shape=shape,
    )
    result.not_applicable.update(dict.fromkeys(END_TO_END_KEYS, RING))
    return result


def _torus_pq(torus, source, p, q, p_det, notes):
    """p, q and where each comes from, for a torus knot ``torus`` = (p, q) or None."""
    if torus is None:
        return None, None, "not a torus knot", "not a torus knot"
    p_cfg, q_cfg = torus
    if p is None and source == "knot type" and p_det in torus and p_cfg != q_cfg:
        # T(p, q) = T(q, p): the pair's member the chain winds about the vertical axis is p
        p_cfg, q_cfg = p_det, (q_cfg if p_det == p_cfg else p_cfg)
    label = source or "run file"
    if p is not None:
        p_src = "argument"
    elif p_cfg is not None:
        p, p_src = int(p_cfg), label
    elif p_det is not None:
        p, p_src = p_det, "data"
    else:
        p, p_src = 1, "default"
        notes.append("the chain does not wind around the vertical axis: p = 1 assumed")
    if q is not None:
        q_src = "argument"
    elif q_cfg is not None:
        q, q_src = int(q_cfg), label
    else:
        q_src = "unknown"
    return p, q, p_src, q_src


def recorded_changes(data) -> list[dict]:
    """The knot-type changes run.toml records (``[knotmm] knot_type_changes``), in order."""
    facts = data.get("knotmm", {}) or {}
    return [dict(c) for c in facts.get("knot_type_changes", []) or []]


def _recorded_changes_note(data, kt: KnotTypes) -> list[str]:
    """A note when run.toml's changes and the analysis's differ (types, in order)."""
    run = recorded_changes(data)
    if kt.initial is None:
        return [f"run.toml records knot-type changes: {describe_changes(run)}"] if run else []
    steps = [(c["from"], c["to"]) for c in kt.changes]
    if not run or [(c["from"], c["to"]) for c in run] == steps:
        return []
    return [
        f"run.toml records {describe_changes(run)} (checked every "
        f"{data.get('run.topology_check_interval', '?')} tau_d); the frames show "
        f"{kt.describe_changes() or 'no change'}"
    ]


def analyze_run(
    run_dir,
    t_from: float | None = None,
    t_to: float | None = None,
    p: int | None = None,
    q: int | None = None,
    plots: bool = True,
    frame_interval: float | None = None,
    topology=None,
    out_dir=None,
    knot_samples: int = 40,
) -> AnalysisResult:
    """Load a run, analyse it, and write ``analysis.json`` (and PNG plots) beside it.

    Parameters
    ----------
    run_dir : str or Path
        A run directory or a DCD file (see :func:`load_run`).
    t_from, t_to, p, q, knot_samples
        As in :func:`analyze`.
    plots : bool
        Write ``analysis_timeseries.png``, ``analysis_spectrum.png``,
        ``analysis_collapse.png`` and ``analysis_snapshot.png``.
    frame_interval, topology
        As in :func:`load_run`, for a DCD without ``run.toml``.
    out_dir : str or Path, optional
        Where to write; default the run directory (the DCD's folder for a bare DCD).

    Returns
    -------
    AnalysisResult
        Its ``to_dict()`` is the content written to ``analysis.json``.

    A run still running (a live process holds its directory's lock) is analysed as far as
    it got, with the note "run still running at t = ..." and the key ``run_still_running``
    (time reached, the run's process id); the run removes that ``analysis.json`` when it
    ends (:func:`knotmm.io.rundir.retire_stale_analysis`). If the run ends while it is
    being analysed, it is analysed again, whole.
    """
    for attempt in range(2):
        owner = lock_owner(_run_directory(run_dir))
        data = load_run(run_dir, frame_interval=frame_interval, topology=topology)
        if owner is None and data.directory is not None:
            owner = lock_owner(data.directory)  # a run started (or resumed) meanwhile
        if owner is not None:
            _note_running(data, owner)
        result = analyze(data, t_from=t_from, t_to=t_to, p=p, q=q, knot_samples=knot_samples)
        if owner is not None:
            result.extra[ANALYSIS_RUNNING_KEY] = {
                "time": float(data.times[-1]), "process": owner or None,
            }
        out = Path(out_dir) if out_dir is not None else data.directory
        path = out / ANALYSIS_FILE
        # a read-only or full directory: one line naming it (OutputError; `knotmm analyze`
        # checks the place first, exit 2, and reports a failure here with exit 3)
        with writing(out):
            out.mkdir(parents=True, exist_ok=True)
            if plots:
                from knotmm.analysis.plots import save_plots

                result.plots = [f.name for f in save_plots(result, out)]
            if result.shape is not None:
                write_text_atomic(out / SHAPE_FILE, result.shape.to_csv())
            text = json.dumps(result.to_dict(), indent=2, allow_nan=False) + "\n"
            write_text_atomic(path, text)  # never a half-written analysis.json
        logger.info("wrote %s", path)
        if owner is None or attempt or lock_owner(data.directory) is not None:
            break
        # the run ended while it was analysed, perhaps before this file was written (then
        # its end could not retire it): analyse the whole run now
        logger.info("the run in %s ended during its analysis: analysing it again", out)
    return result


def _run_directory(run_dir) -> Path:
    """The directory whose lock tells whether ``run_dir`` (a directory or a DCD) is live."""
    path = Path(run_dir)
    return path if path.is_dir() else path.parent


def _note_running(data: RunData, owner: int) -> None:
    """Say that the run is still running (in place of "the run stopped early")."""
    t = float(data.times[-1]) if len(data.times) else 0.0
    who = f"process {owner}" if owner else "a live process"
    data.notes = [n for n in data.notes if "the run stopped early" not in n]
    data.notes.insert(
        0,
        f"run still running at t = {t:g} tau_d ({who} holds {LOCK_FILE}): this analysis "
        f"covers the {len(data.times)} frames written so far; the run removes it when it "
        "ends: analyse again then",
    )
