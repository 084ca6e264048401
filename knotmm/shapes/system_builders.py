"""Run-file templates beyond one closed knot: ``[[chains]]``, links and open filaments.

:func:`knotmm.shapes.builder.build_template` hands a run file here when it gives
``[[chains]]`` (:func:`build_chains`), a link (:func:`is_link`: a torus link T(p, q) with
gcd(p, q) > 1, a closed braid whose permutation has several cycles, a LinkInfo name such as
``L4a1``; :func:`build_link`) or an open filament (:func:`is_open`: ``knot.closed = false``
or a kind of :data:`knotmm.shapes.open_chains.OPEN_KINDS`; :func:`build_open`). Each returns
a :class:`knotmm.shapes.template.Template` whose ``layout`` describes its chains. Units: d.
What they take from the run beyond ``[knot]`` and ``[model]`` comes typed: the perturbation
seeds and the longest bond in a :class:`~knotmm.shapes.spec.TemplateSpec`, the memory budget
in a :class:`~knotmm.shapes.resources.RunResources`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from knotmm.errors import TemplateError
from knotmm.knots.identify import topoly_available
from knotmm.model.layout import ChainLayout, chain_ids
from knotmm.shapes.assembly import assemble, closest_between, place
from knotmm.shapes.checks import BOND_TOLERANCE, check_template, submit_knot_check
from knotmm.shapes.curves import braid_cycles
from knotmm.shapes.links import COMMON_LINKS, LINKINFO_NAME, braid_link, named_link, torus_link
from knotmm.shapes.open_chains import OPEN_KINDS, arc, closest_nonbonded_open, helix, straight
from knotmm.shapes.resources import RunResources, check_memory
from knotmm.shapes.spec import TemplateSpec
from knotmm.shapes.template import PendingKnotCheck, Template
from knotmm.shapes.validation import check_int, check_positive, parse_word_text
from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = ["build_chains", "build_link", "build_open", "is_link", "is_open", "perturb"]


def perturb(x: np.ndarray, perturbation: float, seed: int | None, resolved: dict[str, Any],
            notes: list[str]) -> np.ndarray:
    """``x`` (n_beads, 3), in d, with every coordinate of every bead displaced by one normal
    draw of standard deviation ``perturbation`` from ``numpy.random.default_rng(seed)``, in
    bead order, and centred again; ``knot.seed`` goes into ``resolved``, a note into
    ``notes``. ``x`` itself when ``perturbation`` is not positive."""
    if not perturbation > 0.0:
        return x
    x = x + np.random.default_rng(seed).normal(scale=perturbation, size=x.shape)
    x -= x.mean(axis=0)
    resolved["knot.seed"] = int(seed)
    notes.append(f"perturbed by {perturbation:g} d (std per coordinate), seed {seed}")
    return x


def is_open(cfg) -> bool:
    """Whether the ``[knot]`` table asks for an open filament."""
    return cfg["knot.kind"] in OPEN_KINDS or cfg["knot.closed"] is False


def is_link(cfg) -> bool:
    """Whether the ``[knot]`` table describes a link (several closed components)."""
    kind = cfg["knot.kind"]
    if kind == "torus":
        return math.gcd(int(cfg["knot.p"]), int(cfg["knot.q"])) > 1
    if kind == "braid":
        word = cfg["knot.word"]
        if isinstance(word, str):
            try:
                word = parse_word_text(word, "knot.word")
            except TemplateError:
                return False  # the knot path names the problem
        if not (word and all(isinstance(g, int) and g != 0 for g in word)):
            return False
        strands = max(abs(g) for g in word) + 1
        split = {abs(g) for g in word} != set(range(1, strands))  # refused as a knot is
        return not split and len(braid_cycles(word, strands)) > 1
    if kind == "knotinfo":
        name = str(cfg["knot.name"] or "").strip()
        return bool(LINKINFO_NAME.fullmatch(name)) or name.lower() in COMMON_LINKS
    return False


# -- open filaments ---------------------------------------------------------------------------
def build_open(cfg, build_template: Callable, spec: TemplateSpec,
               resources: RunResources) -> Template:
    """An open filament from ``[knot]``: a straight rod, an arc, a helix, or a closed
    template (a knot, a link) cut open between its last bead and its first (a file's chains
    are opened by :func:`knotmm.shapes.file_start.file_chains`).

    A link with ``knot.closed = false`` is cut open component by component: one open chain
    per component, each between its last bead and its first (its linking numbers are then
    not defined and not recorded). ``knot.perturbation`` is applied once, here, to the
    beads of every chain (one normal draw in bead order, as for the closed template).

    Raises
    ------
    TemplateError
        ``knot.closed = true`` with an open kind; too few beads; beads within the steric
        range of each other; bonds past ``run.max_bond_length``.
    """
    kind = cfg["knot.kind"]
    bond = check_positive(cfg["model.bond_length"], "model.bond_length")
    steric = LJ_CUTOFF_FACTOR * check_positive(cfg["model.lj_sigma"], "model.lj_sigma")
    notes: list[str] = []
    resolved: dict[str, Any] = {}
    closed = None
    if kind in OPEN_KINDS:
        if cfg["knot.closed"] is True:
            raise TemplateError(
                f"knot.kind={kind!r} is an open filament: leave knot.closed unset (or false), "
                "or use a closed kind (torus, braid, knotinfo, file)"
            )
        beads = check_int(cfg["knot.beads"], "knot.beads", 2)
        if kind == "straight":
            x = straight(beads, bond)
            description = f"straight rod of {beads} beads"
        elif kind == "arc":
            x = arc(beads, bond, cfg["knot.arc_degrees"])
            description = f"arc of {cfg['knot.arc_degrees']:g} degrees, {beads} beads"
        else:
            x = helix(beads, bond, cfg["knot.helix_radius"], cfg["knot.helix_pitch"])
            description = (f"helix of radius {cfg['knot.helix_radius']:g} d, pitch "
                           f"{cfg['knot.helix_pitch']:g} d, {beads} beads")
        resolved["knot.beads"] = beads
        if cfg["knot.mirror"]:
            x = x * np.array([1.0, 1.0, -1.0])
            description += " (mirror image)"
    else:  # the closed shape unperturbed: the perturbation is applied below, once
        closed = build_template(cfg.replace({"knot.closed": True, "knot.perturbation": 0.0}),
                                identify="skip", spec=spec.unperturbed(), resources=resources)
        x = closed.positions
        resolved.update({k: v for k, v in closed.resolved.items() if k != "knot.seed"})
        description = f"{closed.description.split(', writhe')[0]}, cut open"
        notes.extend(closed.notes)
    lengths = closed.layout.lengths if closed is not None else (x.shape[0],)
    check_memory(resources, x.shape[0])
    perturbation = float(cfg["knot.perturbation"])
    x = perturb(x, perturbation, spec.seed, resolved, notes)
    chains = np.split(x, np.cumsum(lengths)[:-1])
    limit = steric if kind in OPEN_KINDS and perturbation == 0.0 else cfg["model.lj_sigma"]
    for k, chain in enumerate(chains):
        _check_open(cfg, chain, bond, limit, perturbation,
                    "" if len(chains) == 1 else f"component {k}: ", spec.max_bond_length)
    notes.append("open chain: its knot type is not defined (not checked)")
    if len(chains) == 1:
        return Template(
            positions=np.ascontiguousarray(x, dtype=np.float64),
            description=description,
            resolved=resolved,
            writhe=float("nan"),
            knot_type=None,
            notes=notes,
            layout=ChainLayout((x.shape[0],), (False,)),
        )
    return _cut_link(cfg, closed, chains, limit, resolved, notes)


def _check_open(cfg, x: np.ndarray, bond: float, limit: float, perturbation: float,
                what: str, max_bond: float) -> None:
    """Refuse an open chain with a bond past ``max_bond`` (``run.max_bond_length``), beads
    closer than ``limit`` (in d), or (an open kind, unperturbed) bonds off the bond length."""
    kind = cfg["knot.kind"]
    bonds = np.linalg.norm(np.diff(x, axis=0), axis=1)
    if bonds.max() > max_bond:
        raise TemplateError(
            f"knot: {what}the open chain has a bond of {bonds.max():.3f} d, longer than "
            f"run.max_bond_length={max_bond:g}"
            + ("; use a smaller knot.perturbation" if perturbation > 0.0 else "")
        )
    dmin, pair = closest_nonbonded_open(x)
    if dmin < limit:
        raise TemplateError(
            f"knot.kind={kind!r}: {what}beads {pair[0]} and {pair[1]} are {dmin:.3f} d apart, "
            f"inside the steric range {limit:.3f} d; "
            + ("use a larger knot.helix_radius or knot.helix_pitch" if kind == "helix"
               else "use another shape or a smaller knot.perturbation")
        )
    if kind in OPEN_KINDS and perturbation == 0.0 and (
            np.abs(bonds - bond).max() > BOND_TOLERANCE * bond):
        raise TemplateError(f"knot.kind={kind!r}: bonds off the bond length {bond:g} d")


def _cut_link(cfg, closed: Template, chains: list[np.ndarray], limit: float,
              resolved: dict[str, Any], notes: list[str]) -> Template:
    """A link's components as open chains, one each: checked apart, described, its name kept
    (linking numbers are not defined for open chains)."""
    for a, b, d in _close_components(chains, limit):
        raise TemplateError(
            f"knot.kind={cfg['knot.kind']!r}: components {a} and {b} come {d:.3f} d close, "
            f"inside the steric range {limit:.3f} d; use a smaller knot.perturbation"
        )
    parts = [Template(positions=np.ascontiguousarray(c, dtype=np.float64),
                      description=f"component {k}, cut open", resolved={},
                      writhe=float("nan"), knot_type=None,
                      layout=ChainLayout((c.shape[0],), (False,)))
             for k, c in enumerate(chains)]
    name = closed.chain_facts.get("link", "link")
    system = assemble(parts, [f"component {k}" for k in range(len(parts))], limit,
                      {"link": name})
    system.description = f"{name}, {system.description}"  # each part says "cut open"
    system.resolved = resolved
    system.notes = notes
    return system


# -- links ------------------------------------------------------------------------------------
def build_link(cfg, spec: TemplateSpec, resources: RunResources,
               identify: str = "now") -> Template:
    """A link from ``[knot]``: one closed chain per component, their linking numbers.

    ``knot.beads`` is the whole link's bead count, shared among the components in
    proportion to their lengths (:mod:`knotmm.shapes.links`). ``knot.major_radius``,
    ``knot.perturbation`` and ``knot.seed`` act as on a single knot
    (:func:`knotmm.shapes.builder.build_template`): the components lie on the torus of that
    radius (their bonds then relax in the run; close pairs down to ``lj_sigma`` allowed), and
    every bead of the link is displaced by one normal draw of
    ``numpy.random.default_rng(knot.seed or run.seed)``, after which the components are
    checked and their linking numbers measured.

    Raises
    ------
    TemplateError
        An unknown link name, too few beads, a major radius too small for the strands or
        with bonds past ``run.max_bond_length``, components inside the steric range (before
        or after the perturbation).
    """
    from knotmm.knots.linking import linking_numbers

    kind = cfg["knot.kind"]
    beads = check_int(cfg["knot.beads"], "knot.beads", 8)
    explicit = cfg["knot.major_radius"] is not None
    common = {"bond_length": cfg["model.bond_length"], "minor_radius": cfg["knot.minor_radius"],
              "mirror": bool(cfg["knot.mirror"]), "major_radius": cfg["knot.major_radius"]}
    try:
        if kind == "torus":
            shape = torus_link(int(cfg["knot.p"]), int(cfg["knot.q"]), beads, **common)
        elif kind == "braid":
            word = cfg["knot.word"]
            word = parse_word_text(word, "knot.word") if isinstance(word, str) else word
            shape = braid_link(list(word), beads, **common)
        else:
            shape = named_link(str(cfg["knot.name"]), beads, **common)
    except ValueError as exc:
        message = str(exc)
        raise TemplateError(message if message.startswith("knot.") else f"knot: {message}") \
            from None
    check_memory(resources, shape.n_beads)
    components = [np.asarray(x, dtype=np.float64) for x in shape.components]
    notes: list[str] = []
    resolved: dict[str, Any] = {}
    if explicit:
        notes.extend(_link_radius_notes(cfg, shape.bond_lengths, beads))
    perturbation = float(cfg["knot.perturbation"])
    if perturbation > 0.0:
        components, seed = _perturbed(cfg, components, spec.seed)
        resolved["knot.seed"] = seed
        notes.append(f"perturbed by {perturbation:g} d (std per coordinate), seed {seed}")
    _check_bond_range(cfg, components, "knot.major_radius" if explicit else "knot.beads",
                      spec.max_bond_length)
    sigma = cfg["model.lj_sigma"]
    steric = sigma if explicit else LJ_CUTOFF_FACTOR * sigma
    parts = []
    later = identify == "later" and topoly_available()
    for k, x in enumerate(components):
        check = check_template(x, cfg["model.bond_length"], sigma, bond_tolerance=None,
                               identify=identify == "now", min_distance=steric)
        if check.problems:
            raise TemplateError(_link_problem(cfg, f"component {k} of {shape.name}",
                                              check.problems[0]))

        def conclude(check, k=k):
            kt = check.knot_type
            return kt, f"component {k}" + (f", {kt}" if kt else ""), list(check.notes)

        kt, description, _ = conclude(check)
        handle = submit_knot_check(x) if later else None  # judged beside the run
        parts.append(Template(
            positions=np.ascontiguousarray(x, dtype=np.float64), description=description,
            resolved={}, writhe=check.writhe, knot_type=kt, notes=list(check.notes),
            check=check,
            pending=None if handle is None else PendingKnotCheck(handle, None, conclude),
        ))
    if perturbation > 0.0:  # the components were apart before; say what brought them close
        for a, b, d in _close_components(components, steric):
            raise TemplateError(_link_problem(
                cfg, shape.name, f"components {a} and {b} come {d:.3f} d close, inside "
                f"{steric:.3f} d"))
    numbers = linking_numbers(components)
    ids = ChainLayout(tuple(p.n_beads for p in parts)).ids
    facts = {"link": shape.name,
             "linking_numbers": {f"{ids[i]}-{ids[j]}": int(v) for (i, j), v in numbers.items()}}
    system = assemble(parts, [f"component {k}" for k in range(len(parts))], steric, facts)
    system.description = f"{shape.name}, {system.description}"
    system.resolved = {"knot.beads": system.n_beads, **resolved}
    system.notes = notes + system.notes
    return system


def _perturbed(cfg, components: list[np.ndarray], seed: int) -> tuple[list[np.ndarray], int]:
    """The components displaced as a single knot's beads are (one normal draw over all the
    beads, in bead order, from ``seed``; the link's centre kept), and the seed used."""
    x = np.concatenate(components)
    with np.errstate(all="ignore"):
        x = x + np.random.default_rng(seed).normal(scale=float(cfg["knot.perturbation"]),
                                                   size=x.shape)
        x -= x.mean(axis=0)
    if not np.all(np.isfinite(x)):
        raise TemplateError(
            f"knot.perturbation={float(cfg['knot.perturbation']):g} is too large: the beads "
            "leave the range of floating-point numbers; use a perturbation below the bond "
            f"length {cfg['model.bond_length']:g} d"
        )
    cuts = np.cumsum([c.shape[0] for c in components])[:-1]
    return [np.ascontiguousarray(c) for c in np.split(x, cuts)], int(seed)


def _link_problem(cfg, what: str, problem: str) -> str:
    """The one-line refusal of a link whose components fail a check: names the key to change."""
    if float(cfg["knot.perturbation"]) > 0.0:
        return (f"knot.perturbation={float(cfg['knot.perturbation']):g} is too large: after it "
                f"{what}: {problem}; use a smaller perturbation or another knot.seed")
    if cfg["knot.major_radius"] is not None:
        return (f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads="
                f"{cfg['knot.beads']} is too tight: {what}: {problem}; use a larger "
                "knot.major_radius or leave it unset")
    return f"knot: {what}: {problem}; use more knot.beads"


def _link_radius_notes(cfg, chords: tuple[float, ...], beads: int) -> list[str]:
    """The note on bonds that an explicit knot.major_radius leaves off the bond length."""
    bond = cfg["model.bond_length"]
    worst = max(chords, key=lambda c: abs(c - bond))
    rel = (worst - bond) / bond
    if abs(rel) <= BOND_TOLERANCE:
        return []
    return [
        f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads={beads} gives bonds "
        f"up to {100 * abs(rel):.1f}% {'longer' if rel > 0 else 'shorter'} than "
        f"model.bond_length={bond:g} ({', '.join(f'{c:.4f}' for c in chords)} d); they relax "
        "in the run"
    ]


def _check_bond_range(cfg, components: list[np.ndarray], key: str, max_bond: float) -> None:
    """Refuse components with a bond past ``max_bond`` (``run.max_bond_length``: the run's
    first step would)."""
    with np.errstate(over="ignore"):
        longest = max(float(ChainLayout.ring(len(x)).bond_lengths(x).max())
                      for x in components)
    if longest > max_bond:
        if float(cfg["knot.perturbation"]) > 0.0:
            key = "knot.perturbation"
        value = cfg[key]
        raise TemplateError(
            f"{key}={value:g} is too large: the link has a bond of {longest:.3g} d, longer than "
            f"run.max_bond_length={max_bond:g}; use a smaller "
            f"{key}" + (" or leave it unset" if key == "knot.major_radius" else "")
        )


def _close_components(components: list[np.ndarray], limit: float):
    """``(a, b, distance)`` of components closer than ``limit`` (the first pair found)."""
    for a in range(len(components)):
        for b in range(a + 1, len(components)):
            d = closest_between(components[a], components[b])[0]
            if d < limit:
                yield a, b, d


# -- several chains ---------------------------------------------------------------------------
def build_chains(cfg, build_template: Callable, spec: TemplateSpec, resources: RunResources,
                 *, identify: str = "now") -> Template:
    """The system of a run file's ``[[chains]]``: each entry built as a one-chain run file
    would be (:meth:`knotmm.config.RunConfig.chain_config`), turned by its ``rotation``,
    moved to its ``offset``, and checked against the others for overlaps.

    A chain's perturbation seed defaults to ``run.seed + index``, so identical chains are
    perturbed differently (``spec.seeds``: :meth:`knotmm.shapes.spec.TemplateSpec.of`). The
    template's ``resolved`` is the ``[[chains]]`` array with each entry's resolved keys
    (``beads``, ``major_radius``, ``seed``).
    """
    entries = cfg.chains
    parts, names = [], []
    for c, entry in enumerate(entries):
        sub = cfg.chain_config(c)
        try:
            part = build_template(sub, identify=identify, spec=spec.part(c),
                                  resources=resources)
        except TemplateError as exc:
            raise TemplateError(str(exc).replace("knot.", f"chains[{c}].")) from None
        part.positions = place(part.positions, entry["rotation"], entry["offset"])
        for chain, sl in zip(part.parts, part.layout.slices(), strict=False):  # a link's components
            chain.positions = part.positions[sl]
        for key, value in part.resolved.items():
            entry[key.split(".", 1)[1]] = value
        parts.append(part)
        names.append(f"chains[{c}]")
    steric = LJ_CUTOFF_FACTOR * cfg["model.lj_sigma"]
    check_memory(resources, sum(p.n_beads for p in parts))
    facts = {}
    links = _global_links(parts)
    if links:
        facts["links"] = links
    system = assemble(parts, names, steric, facts)
    system.resolved = {"chains": entries}
    return system


def _global_links(parts: list[Template]) -> list[dict]:
    """The links among ``[[chains]]`` parts, in the system's chain names: each link's
    ``chains`` (its components' ids) and its ``linking_numbers`` keyed by them (a part's own
    facts name its components from ``A``)."""
    links, first = [], 0
    for part in parts:
        n = part.layout.n_chains
        if part.chain_facts:
            local, names = ChainLayout(part.layout.lengths).ids, chain_ids(first + n)[first:]
            rename = dict(zip(local, names, strict=True))
            facts = dict(part.chain_facts)
            facts["chains"] = list(names)
            if "linking_numbers" in facts:
                facts["linking_numbers"] = {
                    "-".join(rename[c] for c in pair.split("-")): v
                    for pair, v in facts["linking_numbers"].items()}
            links.append(facts)
        first += n
    return links
