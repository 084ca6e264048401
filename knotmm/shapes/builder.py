"""The one config-aware template builder: a run file's ``[knot]`` table -> a checked start.

:func:`build_template` turns a :class:`knotmm.config.RunConfig` into a checked
:class:`Template` (positions in d, description, the keys the run should record, writhe, knot
type, notes) and raises :class:`knotmm.errors.TemplateError` with one line naming the
run-file key to change. :func:`minimal_beads` finds the smallest bead count a template
needs. Sources (``docs/model.md``, "Starting shapes"): torus knots ``T(p, q)``
(``kind = "torus"``), closed braids (``"braid"``), named knots drawn as closed braids
(``"knotinfo"``) and a frame of a PDB/DCD file (``"file"``).

Beads are placed at equal chord along the curve, so every bond has the same length. When the
major radius is left unset it is chosen so that this length is exactly the model's bond
length; when it is given, the bond length follows from it (perimeter / beads), and the
bonds relax in the run (a note says by how much).

:func:`build_system` turns a run file into the OpenMM objects of its start (Topology,
System, positions): it sits here, above :mod:`knotmm.model`, because it needs the template.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import openmm
import openmm.app

from knotmm.errors import TemplateError
from knotmm.io.structure import read_structure
from knotmm.knots.chirality import UNKNOWN, is_signed, signed_knot_type, unsigned_knot_type
from knotmm.knots.identify import topoly_available
from knotmm.model.system import ChainModel, chain_system, site_positions
from knotmm.model.topology import bead_topology
from knotmm.shapes.checks import (
    BOND_TOLERANCE,
    TemplateCheck,
    check_template,
    closest_nonbonded,
    submit_knot_check,
)
from knotmm.shapes.curves import braid_curve, circle_curve, torus_curve
from knotmm.shapes.file_start import build_file, file_chains, file_source, source_note
from knotmm.shapes.geometry import TooFewBeadsError, mirror_image, place_on_curve
from knotmm.shapes.knotinfo import TORUS_NAMES, named_knot_word, resolve_name, symmetry_type
from knotmm.shapes.resources import RunResources, check_memory
from knotmm.shapes.spec import TemplateSpec
from knotmm.shapes.system_builders import (
    build_chains,
    build_link,
    build_open,
    is_link,
    is_open,
    perturb,
)
from knotmm.shapes.template import PendingKnotCheck, Template
from knotmm.shapes.validation import (
    RUN_FILE_KEYS,
    check_int,
    check_positive,
    check_torus,
    check_word,
)
from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = ["Template", "build_system", "build_template", "minimal_beads"]

logger = logging.getLogger(__name__)

#: Default tube radius of the run files (knot.minor_radius), in d.
SCHEMA_MINOR_RADIUS = 0.6

# Largest bead count tried when looking for the smallest one that works.
MAX_BEADS_SEARCH = 4096


def _signed_type(
    name: str | None, wr: float, symmetry: str = "", amphichiral: bool | None = None
) -> str | None:
    """``name`` signed with its handedness (:func:`knotmm.knots.chirality.signed_knot_type`).

    topoly's sign is kept where it gave one. Else the tables' symmetry type decides whether
    the knot is chiral (topoly's chiral HOMFLY-PT misses the chirality of a few knots, such
    as 9_42), then topoly's answer, then the table of amphichiral knots; a chiral knot
    takes the sign of the writhe.
    """
    if name is None or name == UNKNOWN or is_signed(name):
        return name
    if symmetry:
        amphichiral = "amphicheiral" in symmetry or "amphichiral" in symmetry
    return signed_knot_type(name, wr, amphichiral=amphichiral)


@dataclass
class _Spec:
    """What build_template needs to rebuild the geometry at another bead count."""

    label: str
    expected: str | None
    symmetry: str
    build: Callable[[int], tuple[np.ndarray, float, float]]
    explicit_radius: bool
    resolved: dict[str, Any] = field(default_factory=dict)


def _spec_from_config(cfg, names=RUN_FILE_KEYS) -> _Spec:
    kind = cfg["knot.kind"]
    bond = cfg["model.bond_length"]
    a = cfg["knot.minor_radius"]
    r0 = cfg["knot.major_radius"]
    mirror = bool(cfg["knot.mirror"])
    if kind == "torus":
        p, q = check_torus(cfg["knot.p"], cfg["knot.q"], names)
        curve = torus_curve(p, q, check_positive(a, names["minor_radius"]))
        label = f"T({p},{q})"
        expected = TORUS_NAMES.get((min(p, q), max(p, q)))
        symmetry = "chiral"  # every non-trivial torus knot is chiral
        resolved = {"knot.p": p, "knot.q": q}
    elif kind in ("braid", "knotinfo"):
        if kind == "braid":
            word = check_word(cfg["knot.word"], names)
            label = f"closed braid {list(word)}"
            expected, symmetry = None, ""
            resolved = {"knot.word": list(word)}
        else:
            if cfg["knot.name"] is None:
                raise TemplateError(
                    "knot.name is not set: knot.kind = 'knotinfo' needs a knot name, e.g. "
                    "name = '5_2'"
                )
            if resolve_name(str(cfg["knot.name"])) == "0_1":  # the unknot: a flat circle
                label, expected, symmetry = "0_1 (circle)", "0_1", symmetry_type("0_1")
                resolved = {"knot.name": "0_1"}
                curve = circle_curve()
            else:
                name, word, source = named_knot_word(cfg["knot.name"], names["name"])
                word = check_word(word, names)
                label = f"{name} (braid {list(word)}, {source})"
                expected, symmetry = name, symmetry_type(name)
                resolved = {"knot.name": name}
        if kind == "braid" or expected != "0_1":
            curve = braid_curve(word, check_positive(a, names["minor_radius"]))
    else:
        raise TemplateError(f"knot.kind={kind!r}: expected torus, braid, knotinfo or file")

    def build(beads: int):
        return place_on_curve(curve, beads, bond, r0, mirror, names, label.split(" (")[0])

    return _Spec(label, expected, symmetry, build, r0 is not None, resolved)


def _label_of(spec: _Spec) -> str:
    """Short name of a template spec for messages ("T(2,5)", "5_2", "closed braid [...]")."""
    return spec.label.split(" (")[0]


def _passes(spec: _Spec, beads: int, bond: float, steric: float) -> bool:
    try:
        x, _, chord = spec.build(beads)
    except TemplateError:
        return False
    if abs(chord - bond) > BOND_TOLERANCE * bond:
        return False
    return closest_nonbonded(x)[0] >= steric


def _search_minimal(spec: _Spec, bond: float, steric: float, start: int = 4) -> int | None:
    """Smallest bead count ``n >= start`` such that every count from ``n`` up to a passing
    count found by doubling passes (odd passing counts below a failing one are ignored)."""
    hi = max(start, 16)
    while not _passes(spec, hi, bond, steric):
        hi *= 2
        if hi > MAX_BEADS_SEARCH:
            return None
    n = hi
    while n - 1 >= start and _passes(spec, n - 1, bond, steric):
        n -= 1
    return n


def minimal_beads(cfg) -> int | None:
    """Smallest ``knot.beads`` for which the template of a run file passes the checks.

    Bond lengths and steric distances are checked at each bead count (the knot type is not
    re-checked); a given ``knot.major_radius`` is ignored (left to choose itself), since it
    fixes the bead count. The search assumes that more beads never hurt, which holds for
    the torus and braid shapes (the torus only grows).

    Parameters
    ----------
    cfg : RunConfig
        Run parameters; ``knot.kind`` must not be ``"file"``.

    Returns
    -------
    int or None
        The bead count, or ``None`` if none up to 4096 works (the minor radius is then too
        small for the steric range).
    """
    if cfg["knot.kind"] == "file":
        raise TemplateError("knot.kind='file': the file fixes the number of beads")
    spec = _spec_from_config(_AutoRadius(cfg))
    steric = LJ_CUTOFF_FACTOR * cfg["model.lj_sigma"]
    return _search_minimal(spec, cfg["model.bond_length"], steric)


class _AutoRadius(Mapping):
    """A view of a config with knot.major_radius unset."""

    def __init__(self, cfg):
        self._cfg = cfg

    def __getitem__(self, key):
        return None if key == "knot.major_radius" else self._cfg[key]

    def __iter__(self):
        return iter(self._cfg)

    def __len__(self):
        return len(self._cfg)


def _steric_message(spec: _Spec, cfg, beads: int, steric: float, problem: str) -> str:
    """The one-line error for a template with beads inside the steric range."""
    bond = cfg["model.bond_length"]
    a = cfg["knot.minor_radius"]
    what = _label_of(spec)
    if spec.explicit_radius:
        return (
            f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads={beads} is too "
            f"tight for {what}: {problem}; use a larger knot.major_radius together with more "
            "knot.beads, or leave knot.major_radius unset"
        )
    best = _search_minimal(spec, bond, steric, start=beads + 1)
    if best is not None:
        return (
            f"knot.beads={beads} is too few for {what} at knot.minor_radius={a:g}: {problem}; "
            f"use knot.beads >= {best}"
        )
    larger = f", e.g. {SCHEMA_MINOR_RADIUS:g} (the default)" if a < SCHEMA_MINOR_RADIUS else ""
    return (
        f"knot.minor_radius={a:g} is too small for {what}: {problem}, and no bead count up to "
        f"{MAX_BEADS_SEARCH} helps; use a larger knot.minor_radius{larger}"
    )


def _explicit_radius_notes(cfg, beads: int, chord: float) -> list[str]:
    """The note on bonds that an explicit knot.major_radius leaves off the bond length."""
    bond = cfg["model.bond_length"]
    rel = (chord - bond) / bond
    if abs(rel) <= BOND_TOLERANCE:
        return []
    return [
        f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads={beads} gives bonds "
        f"of {chord:.4f} d, {100 * abs(rel):.1f}% {'longer' if rel > 0 else 'shorter'} than "
        f"model.bond_length={bond:g}; they relax in the run"
    ]


def _relaxed_notes(check: TemplateCheck, cfg, is_file: bool, max_bond: float,
                   closure_added: bool = False) -> list[str]:
    """Notes on a start checked loosely (a file, an explicit radius); an error for bonds past
    ``max_bond`` (``run.max_bond_length``), which would stop the run at its first step
    (``closure_added``: the file's chain was open, ``knot.closed = true`` closed it)."""
    bond, steric = cfg["model.bond_length"], check.steric_range
    notes = []
    if check.min_distance < steric:
        notes.append(
            f"beads {check.closest_pair[0]} and {check.closest_pair[1]} are "
            f"{check.min_distance:.3f} d apart, inside the steric range {steric:.3f} d"
        )
    if is_file and check.bond_error > BOND_TOLERANCE:
        notes.append(
            f"bonds range {check.bond_min:.3f}-{check.bond_max:.3f} d "
            f"(model.bond_length={bond:g})"
        )
    if check.bond_max > max_bond:
        where = (
            f"knot.path={cfg['knot.path']!r} frame {cfg['knot.frame']}"
            if is_file
            else f"knot.major_radius={cfg['knot.major_radius']:g}"
        )
        hint = (
            "is this a knotmm chain in bead order?"
            if is_file
            else "use a smaller knot.major_radius or more knot.beads"
        )
        if closure_added and check.worst_bond == check.n_beads - 1:
            hint = "the closure knot.closed = true adds is that long: leave knot.closed unset"
        raise TemplateError(
            f"{where}: bond {check.worst_bond}-{(check.worst_bond + 1) % check.n_beads} is "
            f"{check.bond_max:.3f} d, longer than "
            f"run.max_bond_length={max_bond:g}; {hint}"
        )
    return notes


def build_template(cfg, *, identify: str = "now", spec: TemplateSpec | None = None,
                   resources: RunResources | None = None) -> Template:
    """Build and check the starting shape a run file asks for.

    A run file's ``[[chains]]`` (several chains in one fluid), a link (a torus link, a
    closed braid of several components, a LinkInfo name) and an open filament
    (``knot.closed = false``; kinds ``straight``, ``arc``, ``helix``) are built by
    :mod:`knotmm.shapes.system_builders`; the returned template then has a ``layout`` of its
    chains and, for several chains, their own templates as ``parts``. A file
    (``knot.kind = "file"``) starts as the chains its bonds make
    (:func:`knotmm.shapes.file_start.file_chains`: rings, open chains, links; an explicit
    ``knot.closed`` opens or closes every chain): one ring here, any other system by
    :func:`knotmm.shapes.file_start.build_file`; the template records where it came from
    (:attr:`Template.source`).

    Parameters
    ----------
    cfg : RunConfig
        Uses ``knot.*`` (kind, p, q, word, name, path, frame, topology, beads,
        minor_radius, major_radius, mirror, perturbation), ``model.bond_length`` and
        ``model.lj_sigma``; never a ``run.*`` key (``spec`` and ``resources`` hold what the
        template takes from the ``[run]`` table).
    identify : {"now", "later", "skip"}, optional
        When the knot type is identified (topoly, in the knot worker): ``"now"`` waits for
        it; ``"later"`` (a run, which must not wait for topoly's start-up) sends the
        template to the worker and returns: :meth:`Template.settle_knot_type` judges the
        answer once it is back, and a wrong knot type raises there; ``"skip"``: not at all.
    spec : TemplateSpec, optional
        The perturbation's seed of each chain and the longest bond accepted (the run plan's,
        :attr:`knotmm.plan.RunPlan.template`); default :meth:`TemplateSpec.of` of ``cfg``.
    resources : RunResources, optional
        What the run's memory depends on (the run plan's,
        :attr:`knotmm.plan.RunPlan.resources`); default :meth:`RunResources.of` of ``cfg``.

    Returns
    -------
    Template
        Centred positions in d, a description, the resolved keys to record
        (``knot.major_radius`` when chosen automatically, ``knot.beads`` for a file,
        ``knot.seed`` when a perturbation was applied), writhe, knot type and notes.

    Raises
    ------
    TemplateError
        With one line naming the run-file key to change: an impossible specification (a
        unknown name), too few beads, beads inside the steric range
        (closer than ``lj_sigma`` for a file or an explicit ``knot.major_radius``), bonds
        past ``run.max_bond_length``, a template of the wrong knot type, or a file whose
        chains overlap.
    TrajectoryFileError
        For ``knot.kind = "file"`` with a missing, truncated or mismatched file.
    ConfigError
        When the run's dense Brownian noise cannot fit in the memory available
        (:func:`knotmm.shapes.resources.check_memory`).

    Notes
    -----
    With ``knot.major_radius`` unset the bonds come out at ``model.bond_length`` (within
    0.5 %). An explicit radius fixes the bond length at perimeter / beads instead; the bonds
    relax in the run, a note says by how much, and :attr:`Template.facts` records the
    starting range (``template_bond_range``).

    A perturbation (``knot.perturbation`` > 0) adds independent normal displacements of that
    standard deviation, in d, to every coordinate of every bead, drawn from
    ``numpy.random.default_rng(knot.seed or run.seed)`` (``spec.seeds``). Bond lengths are
    checked before the perturbation, the steric distance and the knot type after it.
    """
    spec = TemplateSpec.of(cfg) if spec is None else spec
    resources = RunResources.of(cfg) if resources is None else resources
    if getattr(cfg, "chains", None) is not None:
        return build_chains(cfg, build_template, spec, resources, identify=identify)
    kind = cfg["knot.kind"]
    structure = None
    if kind == "file":
        structure = read_structure(
            cfg["knot.path"], cfg["knot.frame"], cfg["knot.topology"], RUN_FILE_KEYS
        )
        chains = file_chains(structure, cfg["knot.closed"])
        if not chains.layout.is_single_ring:
            tpl = build_file(cfg, structure, chains, spec, resources, identify=identify)
            return _from_file(tpl, structure)
    elif is_open(cfg):
        return build_open(cfg, build_template, spec, resources)
    elif is_link(cfg):
        return build_link(cfg, spec, resources, identify=identify)
    bond = check_positive(cfg["model.bond_length"], "model.bond_length")
    sigma = check_positive(cfg["model.lj_sigma"], "model.lj_sigma")
    steric = LJ_CUTOFF_FACTOR * sigma
    notes: list[str] = []
    resolved: dict[str, Any] = {}
    shape = None
    if structure is not None:
        x = structure.positions - structure.positions.mean(axis=0)
        if cfg["knot.mirror"]:
            x = mirror_image(x)
        n = x.shape[0]
        resolved["knot.beads"] = n
        if cfg["knot.beads"] != n:
            notes.append(f"knot.beads={cfg['knot.beads']} ignored: the file holds {n} beads")
        notes.extend(chains.notes)
        label = f"{structure.path.name} frame {structure.frame}"
        expected, symmetry = None, ""
    else:
        shape = _spec_from_config(cfg)
        beads = check_int(cfg["knot.beads"], "knot.beads", 4)
        what = _label_of(shape)
        try:
            x, r0, chord = shape.build(beads)
        except TooFewBeadsError as exc:
            best = _search_minimal(shape, bond, steric, start=beads + 1)
            if best is None:
                raise
            detail = str(exc).split(": ", 1)[1].split("; use")[0]
            raise TemplateError(
                f"knot.beads={beads} is too few for {what}: {detail}; use knot.beads >= {best}"
            ) from None
        resolved.update(shape.resolved)
        resolved["knot.major_radius"] = r0
        resolved["knot.beads"] = beads
        label, expected, symmetry = shape.label, shape.expected, shape.symmetry
        if shape.explicit_radius:
            notes.extend(_explicit_radius_notes(cfg, beads, chord))
        # an explicit radius may leave bonds off their length (they relax in the run): only
        # overlaps deeper than sigma, which the steric force may not resolve, are refused
        pre = check_template(
            x,
            bond,
            sigma,
            identify=False,
            bond_tolerance=None if shape.explicit_radius else BOND_TOLERANCE,
            min_distance=sigma if shape.explicit_radius else None,
        )
        if pre.problems:
            raise TemplateError(_steric_message(shape, cfg, beads, steric, pre.problems[0]))

    check_memory(resources, x.shape[0])
    perturbation = float(cfg["knot.perturbation"])
    mirror = bool(cfg["knot.mirror"])
    x = perturb(x, perturbation, spec.seed, resolved, notes)

    is_file = kind == "file"
    # files and explicit radii start off the model's bond length: bonds and close pairs down
    # to sigma are allowed (they relax in the run), and noted
    relaxed = is_file or shape.explicit_radius
    later = identify == "later" and topoly_available()
    check = check_template(
        x,
        bond,
        sigma,
        bond_tolerance=None if (relaxed or perturbation > 0.0) else BOND_TOLERANCE,
        expected_knot=expected,
        identify=not later and identify != "skip",
        min_distance=sigma if relaxed else None,
    )
    if relaxed:
        notes.extend(_relaxed_notes(check, cfg, is_file, spec.max_bond_length,
                                    is_file and bool(chains.added)))
    where = f"knot.path={cfg['knot.path']!r} frame {cfg['knot.frame']}" if is_file else ""

    def conclude(check: TemplateCheck) -> tuple[str | None, str, list[str]]:
        """Knot type, description and the check's notes; TemplateError on a problem."""
        if check.problems:
            problem = check.problems[0]
            if perturbation > 0.0:
                raise TemplateError(
                    f"knot.perturbation={perturbation:g} is too large: after it {problem}; "
                    "use a smaller perturbation or another knot.seed"
                )
            if is_file:
                raise TemplateError(f"{where}: {problem}; pick another knot.frame")
            raise TemplateError(f"knot.kind={kind!r} {label}: {problem}; use more knot.beads")
        found = list(check.notes)
        if check.knot_type == "0_1" and kind == "braid":
            found.append("the braid closes to the unknot")
        wr = check.writhe
        if is_file:
            description = f"{label}, writhe {wr:+.2f}"
            if check.knot_type not in (None, UNKNOWN):
                description = f"{check.knot_type} from {description}"
            return check.knot_type, description, found
        sym = symmetry
        if not sym and check.knot_type not in (None, UNKNOWN) and "|" not in check.knot_type:
            sym = symmetry_type(unsigned_knot_type(check.knot_type))
        knot_type = _signed_type(check.knot_type, wr, sym, check.amphichiral)
        shown = knot_type if knot_type not in (None, UNKNOWN) else None
        shown = shown or _signed_type(expected, wr, sym) or f"writhe {wr:+.2f}"
        description = f"{label}, {shown}"
        if mirror:
            description += " (mirror image)"
        return knot_type, description, found

    knot_type, description, found = conclude(check)
    notes.extend(found)
    for note in notes:
        logger.info("template: %s", note)
    tpl = Template(
        positions=np.ascontiguousarray(x, dtype=np.float64),
        description=description,
        resolved=resolved,
        writhe=check.writhe,
        knot_type=knot_type,
        notes=notes,
        check=check,
        pending=_deferred_check(x, expected, conclude) if later else None,
    )
    return tpl if structure is None else _from_file(tpl, structure)


def _from_file(tpl: Template, structure) -> Template:
    """``tpl`` with the record of the file it was read from and the note that says so."""
    tpl.source = file_source(structure)
    note = source_note(structure)
    tpl.notes.append(note)
    logger.info("template: %s", note)
    return tpl


def _deferred_check(x, expected, conclude) -> PendingKnotCheck | None:
    """The template's knot identification, sent to the worker (None if it cannot be)."""
    handle = submit_knot_check(x)
    return None if handle is None else PendingKnotCheck(handle, expected, conclude)


def build_system(cfg) -> tuple[openmm.app.Topology, openmm.System, np.ndarray]:
    """The OpenMM objects of a run file's start: Topology, System and positions.

    The template is :func:`build_template`'s (checked, centred, with any perturbation);
    the System is :func:`knotmm.model.system.chain_system` with the run file's ``[model]``
    table; the Topology is :func:`knotmm.model.topology.bead_topology`. Units: 1 d reads as
    1 nm, 1 F0 d as 1 kJ/mol (``docs/model.md``), so the objects can go straight into an
    ``openmm.Context`` or ``openmm.app.Simulation``.

    Parameters
    ----------
    cfg : RunConfig

    Returns
    -------
    topology : openmm.app.Topology
        One residue ``BEA`` per bead, the ring bonds.
    system : openmm.System
        The four named forces (``bond``, ``bend``, ``steric``, ``gravity``).
    positions : ndarray, shape (n_particles, 3), float64, in nm (= d)
        One row per particle of the System: the ``n_beads`` beads, followed, with
        ``model.segment_repulsion``, by one midpoint per bond of the layout (virtual sites,
        which the Topology does not list).

    Raises
    ------
    TemplateError, TrajectoryFileError
        As :func:`build_template`.

    Examples
    --------
    >>> from knotmm.config import RunConfig
    >>> topology, system, positions = build_system(RunConfig.from_dict({"knot": {"beads": 60}}))
    >>> topology.getNumAtoms(), system.getNumParticles(), positions.shape
    (60, 60, (60, 3))
    """
    template = build_template(cfg)
    model = ChainModel.from_config(cfg)
    system = chain_system(template.positions, model, template.layout)
    topology = bead_topology(template.layout)
    positions = site_positions(template.positions, model, template.layout)
    return topology, system, np.array(positions, dtype=np.float64)
