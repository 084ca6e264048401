"""The largest sizes and numbers a run may ask for, each with the reason it cannot be larger.

Every limit follows from what knotmm's numbers and files can represent, not from taste:

* lengths (coordinates, radii, offsets) up to :data:`MAX_LENGTH` = 1e5 d: the trajectory
  stores float32 Angstrom (1 d = 10 A), which at 1e6 A resolves 0.06 A, 1 % of a bond;
* at most :data:`MAX_BEADS` beads: topology.pdb numbers its atoms with 5 digits;
* at most :data:`MAX_REPLICAS` replicas: each replica's seed is one 32-bit word, and at
  10000 two of them agree with a chance of about 1 %;
* at most :data:`MAX_THREADS` threads: each reserves an 8 MB stack;
* at most :data:`MAX_FRAMES` frames: the DCD header counts them in a 32-bit integer;
* speeds: a bead falls ``gravity`` d and diffuses ``sqrt(2 / Pe)`` d per tau_d, so
  :data:`MAX_GRAVITY` and :data:`MIN_PECLET` keep one tau_d's motion within MAX_LENGTH (and
  ``kT = 1 / Pe`` finite);
* a movie frame of 12 x 4.6 inches at up to :data:`MAX_DPI`: 7200 x 2760 pixels, within
  H.264's largest frame (8192 x 4320);
* the strands of a braid and the windings of a torus knot no more than its beads
  (:func:`check_shape_sizes`), so that a generator of 2^63 allocates nothing.

:mod:`knotmm.config` holds the run-file keys to them before anything is built or allocated;
the checks here raise :class:`knotmm.errors.ConfigError` with one line naming the key, the
value, the limit and its reason. Units: model units (d, F0, tau_d).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any

from knotmm.errors import ConfigError

__all__ = [
    "BEADS_WHY",
    "GRAVITY_WHY",
    "LENGTH_WHY",
    "MAX_BEADS",
    "MAX_DPI",
    "MAX_FRAMES",
    "MAX_GRAVITY",
    "MAX_LENGTH",
    "MAX_REPLICAS",
    "MAX_THREADS",
    "MIN_PECLET",
    "PECLET_WHY",
    "REPLICAS_WHY",
    "THREADS_WHY",
    "as_float",
    "check_frames",
    "check_steps",
    "check_placement",
    "check_shape_sizes",
    "check_total_beads",
    "shown",
]

#: Largest length a run may give (a coordinate, a radius, an offset), in d.
MAX_LENGTH = 1e5
LENGTH_WHY = "past 1e5 d the float32 trajectory (Angstrom) no longer resolves a bond"
#: Most beads in one run.
MAX_BEADS = 99_999
BEADS_WHY = "topology.pdb numbers its atoms with 5 digits"
#: Most replicas of one run: the chance that two of their 32-bit seeds agree is about 1 %.
MAX_REPLICAS = 10_000
REPLICAS_WHY = ("each replica's seed is one 32-bit word: with 10000 replicas two share a seed "
                "with a chance of about 1 %, and more only raise it")
#: Most threads of one run (run.threads, run.mobility_threads).
MAX_THREADS = 128
THREADS_WHY = ("each is an OS thread that reserves an 8 MB stack: 128 reserve 1 GB of address "
               "space, and more would find no cores to run on")
#: Largest gravity, in F0: a bead falls gravity d per tau_d.
MAX_GRAVITY = MAX_LENGTH
GRAVITY_WHY = ("a bead falls gravity d per tau_d: past 1e5 its chain leaves the 1e5 d that the "
               "float32 trajectory resolves within one tau_d")
#: Smallest finite Peclet number: a bead diffuses sqrt(2 / Pe) d per tau_d.
MIN_PECLET = 2.0 / MAX_LENGTH**2
PECLET_WHY = ("kT = 1/Pe: a bead diffuses sqrt(2/Pe) d per tau_d, below that past the 1e5 d "
              "that the float32 trajectory resolves")
#: Most steps of one run: OpenMM and the checkpoints count them in a signed 64-bit integer.
MAX_STEPS = 2**63 - 1
#: Most frames of one trajectory (the DCD header's 32-bit count).
MAX_FRAMES = 2**31 - 1
#: Largest movie resolution, in dots per inch of the 12 x 4.6 inch frame.
MAX_DPI = 600.0


def shown(value: Any) -> str:
    """``repr(value)``, cut to 60 characters, so that a 400-digit integer stays one line."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def as_float(value: int | float) -> float:
    """``float(value)``, NaN for an integer past the float range (a 400-digit TOML integer)."""
    try:
        return float(value)
    except OverflowError:
        return float("nan")


def check_placement(offset: Sequence[float], rotation: Sequence[float] | None,
                    where: str) -> None:
    """Check a chain's ``offset`` (3 numbers within :data:`MAX_LENGTH`) and ``rotation``
    (``[x, y, z, degrees]``, an axis whose direction float64 can compute).

    The axis is scaled by its largest component before its norm is taken
    (:func:`knotmm.shapes.assembly.rotation_matrix`), so any size works (1e200 too) but one
    whose largest component is zero or subnormal (below 2.2e-308: no precision left), and
    such an axis has no direction.

    Raises
    ------
    ConfigError
        Naming ``{where}offset`` or ``{where}rotation``, the value and what is expected.
    """
    if len(offset) != 3 or max(map(abs, offset)) > MAX_LENGTH:
        raise ConfigError(f"{where}offset = {shown(offset)}: expected [x, y, z], 3 numbers in "
                          f"d, each within +-{MAX_LENGTH:g} ({LENGTH_WHY})")
    if rotation is not None and (len(rotation) != 4
                                 or max(map(abs, rotation[:3])) < sys.float_info.min):
        raise ConfigError(
            f"{where}rotation = {shown(rotation)}: expected [x, y, z, degrees] with a non-zero "
            f"axis (x, y, z) whose largest part is at least {sys.float_info.min:.3g} (smaller "
            "parts leave its direction undefined), e.g. [0, 0, 1, 90]"
        )


def check_total_beads(chains: Sequence[Mapping[str, Any]]) -> None:
    """Refuse ``[[chains]]`` entries whose beads and the TER records between them need more
    than :data:`MAX_BEADS` atom serials in topology.pdb (entries of kind ``file`` take their
    count from the file and are not counted here)."""
    total = sum(entry["beads"] for entry in chains if entry["kind"] != "file")
    most = MAX_BEADS - (len(chains) - 1)  # a TER record between chains takes a serial too
    if total > most:
        raise ConfigError(f"chains: {total} beads in all (the sum of chains[i].beads), more "
                          f"than {most} for {len(chains)} chains ({BEADS_WHY}, the TER records "
                          "between chains included); use fewer beads or chains")


def check_shape_sizes(knot: Mapping[str, Any], where: str) -> None:
    """Hold what a template's shape implies to its bead count, before anything is allocated.

    The strands of a closed braid (``max |g| + 1`` for a word of generators ``g``) and the
    windings of a torus knot ``T(p, q)`` (p around its axis, q through its hole) each go once
    around the template with beads of their own, so neither can outnumber the beads.

    Parameters
    ----------
    knot : mapping
        A validated ``[knot]`` table or ``[[chains]]`` entry (``kind``, ``beads``, ``p``,
        ``q``, ``word``).
    where : str
        How its keys are named: ``"knot."`` or ``"chains[1]."``.

    Raises
    ------
    ConfigError
        Naming the key, its value and the bead count.
    """
    beads, kind, word = knot["beads"], knot["kind"], knot["word"]
    if kind == "torus" and max(knot["p"], knot["q"]) > beads:
        raise ConfigError(
            f"{where}p = {shown(knot['p'])}, {where}q = {shown(knot['q'])}: T(p, q) winds p "
            "times around its axis and q times through its hole, each with beads of its own, "
            f"so neither may exceed {where}beads = {beads}; use smaller p and q or more beads"
        )
    if kind == "braid" and word and max(map(abs, word)) >= beads:
        top = max(map(abs, word))
        raise ConfigError(
            f"{where}word = {shown(word)}: generator {shown(top)} asks for {shown(top + 1)} "
            f"strands, each going once around with beads of its own, more than {where}beads "
            f"= {beads}; use generators below {beads}"
        )


def check_steps(duration: float, largest_step: float, key: str) -> None:
    """Refuse a run that needs more than :data:`MAX_STEPS` steps to reach ``duration``.

    ``largest_step`` (tau_d) is the largest step the run may take: the step of a fixed-step
    integrator, ``run.max_timestep`` of an adaptive one; ``key`` names it.
    """
    if duration / largest_step > MAX_STEPS:
        raise ConfigError(
            f"{key} = {largest_step!r} needs more than 2^63 steps to reach run.duration = "
            f"{duration!r} tau_d, more than OpenMM's 64-bit step count can hold (the run could "
            f"never finish); allow larger steps or a shorter run"
        )


def check_frames(duration: float, frame_interval: float) -> None:
    """Refuse a run whose trajectory would hold more than :data:`MAX_FRAMES` frames."""
    if duration / frame_interval > MAX_FRAMES:
        raise ConfigError(
            f"run.duration = {duration!r} with output.frame_interval = {frame_interval!r} "
            f"makes more than {MAX_FRAMES} frames, which the DCD header's 32-bit frame count "
            "cannot hold; write frames less often (a larger output.frame_interval)"
        )
