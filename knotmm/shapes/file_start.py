"""A start read from a file (``knot.kind = "file"``): its chains as the file says.

:func:`file_chains` decides which chains a frame read by
:func:`knotmm.io.structure.read_structure` starts as: those of the file's bonds (CONECT
records; a knotmm ``topology.pdb`` of one ring, several chains, open chains or a link reads
back as written), changed only by an explicit ``knot.closed``:

* unset: as the file says; a file without bonds: each PDB chain a ring in atom order (noted);
* ``false``: every chain open, each ring cut between its last bead and its first (as
  ``closed = false`` cuts a link's components);
* ``true``: every chain closed, each open chain closed from its last bead to its first.

Chains are never joined into one. One ring goes on through the single-knot path of
:func:`knotmm.shapes.builder.build_template` (knot type, writhe, bond checks);
:func:`build_file` builds every other start: each chain checked alone (a ring: its knot type,
an open chain: none), the chains apart, the linking numbers of the rings. Either way the
template records where it came from (:attr:`Template.source`: the file, the frame, its time
in the run that wrote it); the new run's time starts at 0. Units: d.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from knotmm.errors import TemplateError
from knotmm.knots.identify import topoly_available
from knotmm.model.layout import ChainLayout
from knotmm.shapes.assembly import assemble, closest_between
from knotmm.shapes.checks import BOND_TOLERANCE, check_template, submit_knot_check
from knotmm.shapes.geometry import mirror_image
from knotmm.shapes.open_chains import closest_nonbonded_open
from knotmm.shapes.resources import RunResources, check_memory
from knotmm.shapes.spec import TemplateSpec
from knotmm.shapes.system_builders import perturb
from knotmm.shapes.template import PendingKnotCheck, Template
from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = ["FileChains", "build_file", "file_chains", "file_source"]


@dataclass(frozen=True)
class FileChains:
    """The chains a file start takes: ``layout``, the notes saying how they were read, and
    ``added``: the chains whose ring closure ``knot.closed = true`` added (their closing
    bond is not the file's)."""

    layout: ChainLayout
    notes: tuple[str, ...] = ()
    added: frozenset[int] = frozenset()


def _named(ids, chains) -> str:
    chains = list(chains)
    label = "chain" if len(chains) == 1 else "chains"
    return f"{label} {', '.join(ids[c] for c in chains)}"


def file_chains(structure, closed: bool | None) -> FileChains:
    """The chains of a file start: the file's (:attr:`Structure.layout`), or, for a file
    without bonds, one ring per PDB chain; then ``closed`` (``knot.closed``) applied.

    Parameters
    ----------
    structure : knotmm.io.structure.Structure
    closed : bool or None
        ``knot.closed``: None keeps the file's chains; False opens every ring (cut between
        its last bead and its first); True closes every open chain.

    Raises
    ------
    TemplateError
        ``closed = true`` on an open chain too short to be a ring (2 beads).
    """
    name = structure.path.name
    n = structure.positions.shape[0]
    notes: list[str] = []
    layout = structure.layout
    if layout is None:
        chains = structure.pdb_chains
        if len(chains) > 1 and sum(chains) == n:
            layout = ChainLayout(tuple(chains), (True,) * len(chains))
            notes.append(f"{name} lists no bonds: each of its {len(chains)} PDB chains is taken "
                         "as a ring in atom order, its last bead bonded to its first")
        elif structure.ring_closed is None:
            layout = ChainLayout.ring(n)
            notes.append(f"{name} lists no bonds: the chain is taken as a ring in atom order, "
                         f"bead {n - 1} bonded to bead 0")
        else:
            layout = ChainLayout((n,), (bool(structure.ring_closed),))
    if closed is None or all(r == closed for r in layout.closed):
        return FileChains(layout, tuple(notes))
    ids = layout.ids
    changed = [c for c, ring in enumerate(layout.closed) if ring != closed]
    if closed:
        short = [c for c in changed if layout.lengths[c] < 3]
        if short:
            raise TemplateError(
                f"knot.closed = true: {_named(ids, short)} of {name} "
                f"{'has' if len(short) == 1 else 'have'} 2 beads, too few for a ring; leave "
                "knot.closed unset to keep the file's open chains"
            )
        what = (f"{_named(ids, changed)} of {name} closed here" if layout.n_chains > 1
                else f"{name} is an open chain: closed here")
        notes.append(f"knot.closed = true: {what}, the last bead bonded to the first")
    else:
        what = (f"{_named(ids, changed)} of {name} cut open" if layout.n_chains > 1
                else f"the ring of {name} cut open")
        notes.append(f"knot.closed = false: {what} between the last bead and the first"
                     + (" (linking numbers are not defined for open chains)"
                        if layout.n_chains > 1 else ""))
    new = ChainLayout(layout.lengths, (bool(closed),) * layout.n_chains)
    return FileChains(new, tuple(notes), frozenset(changed) if closed else frozenset())


def file_source(structure) -> dict[str, Any]:
    """What run.toml records of where a file start came from (``[knotmm.started_from]``):
    the file, the frame, the frames it holds, its topology, the run directory and the
    frame's time there (in tau_d) when known."""
    source: dict[str, Any] = {"path": str(structure.path.resolve()),
                              "frame": int(structure.frame),
                              "frames": int(structure.n_frames)}
    if structure.topology is not None:
        source["topology"] = str(structure.topology.resolve())
    if structure.run_directory is not None:
        source["run"] = str(structure.run_directory.resolve())
    if structure.frame_time is not None:
        source["time"] = float(structure.frame_time)
    return source


def source_note(structure) -> str:
    """The note that says where a file start came from and that the run starts at t = 0."""
    at = (f"; t = {structure.frame_time:g} tau_d in run {structure.run_directory.name}"
          if structure.frame_time is not None else "")
    frames = f"{structure.n_frames} frame{'s' if structure.n_frames != 1 else ''}"
    return (f"start: frame {structure.frame} of {structure.path.name} ({frames}{at}); a run "
            "from it counts its time from 0")


def build_file(cfg, structure, chains: FileChains, spec: TemplateSpec,
               resources: RunResources, identify: str = "now") -> Template:
    """A start of several chains, or of one open chain, from a file.

    The positions are the file's frame centred (the system's centre of mass at the origin),
    mirrored with ``knot.mirror``, displaced with ``knot.perturbation`` (one normal draw
    over every bead, in bead order, from ``spec.seed``, as a link's). Each chain is
    checked alone, as a file's one ring is (bonds past ``run.max_bond_length`` refused,
    beads closer than ``lj_sigma`` refused, closer than the steric range noted): a ring's
    knot type is identified (``identify`` as :func:`knotmm.shapes.builder.build_template`'s),
    an open chain has none. Chains closer than ``lj_sigma`` to each other are refused. The
    linking numbers of every pair of rings go into ``chain_facts`` (``linking_numbers``).

    Parameters
    ----------
    cfg : RunConfig
        ``knot.*`` and ``model.*`` keys (never ``run.*``).
    structure : knotmm.io.structure.Structure
    chains : FileChains
        :func:`file_chains` of ``structure``.
    spec, resources
        As :func:`knotmm.shapes.builder.build_template`'s.
    identify : {"now", "later", "skip"}

    Raises
    ------
    TemplateError
        One line naming ``knot.path`` and the frame, the chain and what to change.
    """
    from knotmm.knots.linking import linking_numbers  # noqa: PLC0415 - Gauss integral

    layout = chains.layout
    where = f"knot.path={cfg['knot.path']!r} frame {structure.frame}"
    x = structure.positions - structure.positions.mean(axis=0)
    if cfg["knot.mirror"]:
        x = mirror_image(x)
    n = x.shape[0]
    notes: list[str] = []
    resolved: dict[str, Any] = {"knot.beads": n}
    if cfg["knot.beads"] != n:
        notes.append(f"knot.beads={cfg['knot.beads']} ignored: the file holds {n} beads")
    notes.extend(chains.notes)
    check_memory(resources, n)
    perturbation = float(cfg["knot.perturbation"])
    x = perturb(x, perturbation, spec.seed, resolved, notes)
    bond = float(cfg["model.bond_length"])
    sigma = float(cfg["model.lj_sigma"])
    steric = LJ_CUTOFF_FACTOR * sigma
    fix = ("use a smaller knot.perturbation or another knot.seed" if perturbation > 0.0
           else "pick another knot.frame")
    later = identify == "later" and topoly_available()
    ids = layout.ids
    parts: list[Template] = []
    for c, (sl, ring) in enumerate(zip(layout.slices(), layout.closed, strict=True)):
        xc = np.ascontiguousarray(x[sl])
        one = ChainLayout((xc.shape[0],), (ring,))
        _check_bonds(xc, one, c in chains.added, f"{where}: chain {ids[c]}", spec,
                     perturbation)
        part = (_ring(xc, bond, sigma, identify, later, f"{where}: chain {ids[c]}", fix)
                if ring else _open(xc, sigma, f"{where}: chain {ids[c]}", fix))
        if part.check is not None and part.check.min_distance < steric:
            i, j = part.check.closest_pair
            notes.append(f"chain {ids[c]}: beads {i} and {j} are "
                         f"{part.check.min_distance:.3f} d apart, inside the steric range "
                         f"{steric:.3f} d")
        parts.append(part)
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            d, i, j = closest_between(parts[a].positions, parts[b].positions)
            if d < sigma:
                raise TemplateError(
                    f"{where}: chains {ids[a]} and {ids[b]} come {d:.3f} d close (bead {i} of "
                    f"{ids[a]}, bead {j} of {ids[b]}), closer than the {sigma:.3f} d allowed "
                    f"(model.lj_sigma); {fix}"
                )
    bonds = layout.bond_lengths(x)
    if np.abs(bonds - bond).max() > BOND_TOLERANCE * bond:
        notes.append(f"bonds range {bonds.min():.3f}-{bonds.max():.3f} d "
                     f"(model.bond_length={bond:g})")
    label = f"{structure.path.name} frame {structure.frame}"
    if layout.n_chains == 1:  # one open chain
        notes.append("open chain: its knot type is not defined (not checked)")
        return Template(positions=np.ascontiguousarray(x), description=f"{label}, open chain "
                        f"of {n} beads", resolved=resolved, writhe=float("nan"), knot_type=None,
                        notes=notes, layout=layout)
    rings = [c for c, ring in enumerate(layout.closed) if ring]
    facts: dict[str, Any] = {}
    if len(rings) > 1:
        numbers = linking_numbers([parts[c].positions for c in rings])
        facts["linking_numbers"] = {f"{ids[rings[i]]}-{ids[rings[j]]}": int(v)
                                    for (i, j), v in numbers.items()}
    system = assemble(parts, [f"chain {cid}" for cid in ids], 0.0, facts)
    system.description = f"{label}, {system.description}"
    system.resolved = resolved
    system.notes = notes + system.notes
    return system


def _check_bonds(x: np.ndarray, layout: ChainLayout, added: bool, where: str,
                 spec: TemplateSpec, perturbation: float) -> None:
    """Refuse a chain with a bond past ``run.max_bond_length`` (the run's first step would)."""
    bonds = layout.bond_lengths(x)
    k = int(np.argmax(bonds))
    if bonds[k] <= spec.max_bond_length:
        return
    n = x.shape[0]
    closure = layout.closed[0] and k == n - 1
    if closure and added:
        hint = "the closure knot.closed = true adds is that long: leave knot.closed unset"
    elif perturbation > 0.0:
        hint = "use a smaller knot.perturbation"
    else:
        hint = "is this a knotmm chain in bead order?"
    pair = f"{n - 1}-0" if closure else f"{k}-{k + 1}"
    raise TemplateError(
        f"{where}: bond {pair} is {bonds[k]:.3f} d, longer than "
        f"run.max_bond_length={spec.max_bond_length:g}; {hint}"
    )


def _ring(x: np.ndarray, bond: float, sigma: float, identify: str, later: bool, where: str,
          fix: str) -> Template:
    """One ring of a file, checked: close beads, writhe, knot type (now or in the worker)."""
    n = x.shape[0]
    if n < 4:
        raise TemplateError(f"{where} is a ring of {n} beads: a ring needs at least 4; set "
                            "knot.closed = false to run it open")
    check = check_template(x, bond, sigma, bond_tolerance=None, min_distance=sigma,
                           identify=not later and identify != "skip")
    if check.problems:
        raise TemplateError(f"{where}: {check.problems[0]}; {fix}")

    def conclude(check):
        kt = check.knot_type
        return kt, f"ring of {n}" + (f", {kt}" if kt else ""), list(check.notes)

    kt, description, notes = conclude(check)
    handle = submit_knot_check(x) if later else None
    return Template(positions=x, description=description, resolved={}, writhe=check.writhe,
                    knot_type=kt, notes=notes, check=check,
                    pending=None if handle is None else PendingKnotCheck(handle, None,
                                                                         conclude))


def _open(x: np.ndarray, sigma: float, where: str, fix: str) -> Template:
    """One open chain of a file, checked: no two beads closer than ``sigma``."""
    dmin, (i, j) = closest_nonbonded_open(x)
    if dmin < sigma:
        raise TemplateError(f"{where}: beads {i} and {j} are {dmin:.3f} d apart, closer than "
                            f"the {sigma:.3f} d allowed; {fix}")
    return Template(positions=x, description=f"open chain of {x.shape[0]}", resolved={},
                    writhe=float("nan"), knot_type=None,
                    layout=ChainLayout((x.shape[0],), (False,)))
