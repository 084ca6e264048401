"""``knotmm template``: build, check and write a knot template.

Examples
--------
::

    knotmm template 5_2 --beads 120 --out 5_2.pdb
    knotmm template figure-eight --beads 100
    knotmm template torus:2,3 --beads 60 --mirror --out left_trefoil.pdb
    knotmm template braid:1,-2,1,-2 --beads 100
    knotmm template file:runs/trefoil/trajectory.dcd --frame -1 --out last.pdb
    knotmm template --list
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
import textwrap
from pathlib import Path

from knotmm.config import SCHEMA, RunConfig, parse_override
from knotmm.errors import ConfigError, TemplateError

logger = logging.getLogger(__name__)

_KNOT_HELP = (
    "the knot: a name from the tables (3_1, 5_2, 11a_367) or a common name (trefoil, "
    "figure-eight, cinquefoil, three-twist, stevedore, ...; --list lists them), a link (hopf, "
    "whitehead, borromean, L4a1{1}), torus:P,Q "
    "(e.g. torus:2,3), braid:W (e.g. braid:1,-2,1,-2), or file:PATH (a PDB, a DCD with "
    "its topology, or a run directory: the chains its bonds make; --frame)"
)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``template`` sub-command."""
    parser = subparsers.add_parser(
        "template",
        help="build and check a knot template, write it as PDB",
        description=(
            "Build a starting shape, check it (bond lengths, steric overlaps, knot type with "
            "topoly when installed) and optionally write it as a PDB file with CONECT "
            "records (lengths in Angstrom, 1 d = 10 A)."
        ),
        epilog=textwrap.dedent(__doc__.split("::", 1)[1]).rstrip(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("knot", nargs="?", metavar="KNOT", help=_KNOT_HELP)
    parser.add_argument(
        "--list", action="store_true", help="list the named knots and links available and exit"
    )
    parser.add_argument(
        "--beads",
        "-n",
        type=int,
        default=None,
        help=f"number of beads N (default {SCHEMA['knot']['beads'].default})",
    )
    parser.add_argument("--out", "-o", metavar="FILE.pdb", help="write the template here")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace the --out file if it exists"
    )
    parser.add_argument("--mirror", action="store_true", help="the mirror image (z -> -z)")
    parser.add_argument("--minor-radius", type=float, metavar="A", help="tube radius a, in d")
    parser.add_argument(
        "--major-radius",
        type=float,
        metavar="R0",
        help="torus radius r0, in d (default: chosen so that bonds are the bond length)",
    )
    parser.add_argument(
        "--perturbation",
        type=float,
        metavar="S",
        help="random displacement of each bead coordinate (std), in d",
    )
    parser.add_argument("--seed", type=int, help="seed of the perturbation")
    parser.add_argument("--frame", type=int, help="file: frame index (-1: the last)")
    parser.add_argument("--topology", metavar="PDB", help="file: the topology PDB of a DCD")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="any run-file key, e.g. --set model.lj_sigma=0.45 (repeatable)",
    )
    parser.set_defaults(execute=execute)
    return parser


def parse_knot(text: str) -> dict:
    """Turn a KNOT argument into ``[knot]`` run-file keys.

    Parameters
    ----------
    text : str
        ``"5_2"``, ``"torus:2,3"`` (also ``"T(2,3)"``), ``"braid:1,-2,1,-2"`` or
        ``"file:PATH"`` (a path ending in .pdb or .dcd also works without the prefix).

    Returns
    -------
    dict
        ``{"kind": ..., and p, q / word / name / path}``.

    Raises
    ------
    ConfigError
        For text in none of these forms.
    """
    raw = text.strip()
    head, sep, rest = raw.partition(":")
    head_l = head.strip().lower()
    if sep and head_l == "torus" or re.fullmatch(r"[Tt]\(\s*-?\d+\s*,\s*-?\d+\s*\)", raw):
        body = rest if sep else raw[2:-1]
        numbers = [s for s in re.split(r"[\s,]+", body.strip()) if s]
        try:
            p, q = (int(s) for s in numbers)
        except ValueError:
            raise ConfigError(
                f"KNOT={text!r}: expected torus:P,Q with two integers, e.g. torus:2,3"
            ) from None
        return {"kind": "torus", "p": p, "q": q}
    if sep and head_l == "braid":
        parts = [s for s in re.split(r"[\s,]+", rest.strip().strip("[]")) if s]
        try:
            word = [int(s) for s in parts]
        except ValueError:
            raise ConfigError(
                f"KNOT={text!r}: expected braid:W with signed integers, e.g. braid:1,-2,1,-2"
            ) from None
        if not word:
            raise ConfigError(f"KNOT={text!r}: the braid word is empty; e.g. braid:1,-2,1,-2")
        return {"kind": "braid", "word": word}
    if sep and head_l == "file":
        return {"kind": "file", "path": rest.strip()}
    if sep and head_l in ("knotinfo", "name", "knot"):
        return {"kind": "knotinfo", "name": rest.strip()}
    if raw.lower().endswith((".pdb", ".dcd")):
        return {"kind": "file", "path": raw}
    if sep:
        raise ConfigError(
            f"KNOT={text!r}: unknown prefix {head!r}; use torus:P,Q, braid:W, file:PATH or a "
            "knot name such as 5_2"
        )
    return {"kind": "knotinfo", "name": raw}


def _print_list(out) -> None:
    from knotmm.shapes.knotinfo import (  # noqa: PLC0415
        BUILTIN_BRAIDS,
        COMMON_NAMES,
        knotinfo_available,
        list_named_knots,
    )

    print("built-in knots (braid words; no extra package needed):", file=out)
    for name, word in BUILTIN_BRAIDS.items():
        print(f"  {name:6s} {list(word)}", file=out)
    common = ", ".join(f"{k} ({v})" for k, v in COMMON_NAMES.items() if v != "0_1")
    print(textwrap.fill(f"common names: {common}", width=96, subsequent_indent="  "), file=out)
    _print_links(out, knotinfo_available())
    names = [n for n in list_named_knots() if n not in BUILTIN_BRAIDS]
    if not knotinfo_available():
        print(
            "other knots need the optional package database_knotinfo (pip install 'knotmm[knots]')",
            file=out,
        )
        return
    print(f"from the KnotInfo tables ({len(names)} more knots):", file=out)
    groups: dict[str, list[str]] = {}
    for n in names:
        groups.setdefault(re.match(r"\d+[an]?", n).group(0), []).append(n)
    for family, members in groups.items():
        if len(members) <= 200:
            text = " ".join(members)
        else:
            text = f"{members[0]} ... {members[-1]} ({len(members)} knots)"
        wrapped = textwrap.fill(
            text, width=96, initial_indent=f"  {family:>4s}: ", subsequent_indent=" " * 8
        )
        print(wrapped, file=out)


def _print_links(out, knotinfo: bool) -> None:
    """The links ``--list`` names: the common ones, and how LinkInfo names are written."""
    from knotmm.shapes.links import COMMON_LINKS, LINKINFO_NAME  # noqa: PLC0415

    def shown(kind, data):
        return f"T{data}".replace(" ", "") if kind == "torus" else f"braid {list(data)}"

    print("links (several closed chains; no extra package needed):", file=out)
    for name, (kind, data) in COMMON_LINKS.items():
        print(f"  {name:10s} {shown(kind, data)}", file=out)
    if knotinfo:
        from database_knotinfo import link_list  # noqa: PLC0415

        count = sum(1 for row in link_list(True)
                    if LINKINFO_NAME.fullmatch(str(row.get("name", ""))))
        where = f"{count} oriented links from the LinkInfo tables"
    else:
        where = "they need the optional package database_knotinfo: pip install 'knotmm[knots]'"
    print(textwrap.fill(
        f"LinkInfo names work too, with the orientation in braces (one 0 or 1 per component "
        f"after the first): L4a1{{1}}, L5a1{{0}}, L6a4{{0,0}} ({where})",
        width=96, initial_indent="  ", subsequent_indent="  "), file=out)


def _check_out(out: str, overwrite: bool) -> Path:
    """The ``--out`` path, checked before the template is built."""
    path = Path(out)
    if path.suffix.lower() != ".pdb":
        raise ConfigError(f"--out={out!r}: expected a file name ending in .pdb")
    if path.is_dir():
        raise ConfigError(f"--out={out!r} is a directory; give a file name")
    if path.exists() and not overwrite:
        raise ConfigError(f"--out={out!r} exists; add --overwrite to replace it")
    return path


def execute(args) -> int:
    """Run ``knotmm template``; return the exit code."""
    out = sys.stdout
    if args.list:
        _print_list(out)
        return 0
    if not args.knot:
        raise ConfigError("KNOT is missing: e.g. knotmm template 3_1 --beads 120 --out 3_1.pdb")
    knot = parse_knot(args.knot)
    for option, value in (("--frame", args.frame), ("--topology", args.topology)):
        if value is not None and knot["kind"] != "file":
            raise ConfigError(
                f"{option}={value!r} applies only to a file knot (file:PATH), not to "
                f"KNOT={args.knot!r}; leave {option} out"
            )
    out_path = _check_out(args.out, args.overwrite) if args.out else None
    optional = {
        "beads": args.beads,
        "minor_radius": args.minor_radius,
        "major_radius": args.major_radius,
        "perturbation": args.perturbation,
        "seed": args.seed,
        "frame": args.frame,
        "topology": args.topology,
    }
    knot.update({k: v for k, v in optional.items() if v is not None})
    if args.mirror:
        knot["mirror"] = True
    data: dict = {"knot": knot}
    for text in args.overrides:
        dotted, value = parse_override(text)
        table, _, key = dotted.partition(".")
        data.setdefault(table, {})[key] = value
    cfg = RunConfig.from_dict(data)

    from knotmm.shapes.builder import build_template  # noqa: PLC0415

    tpl = build_template(cfg)  # a file: its chains as its bonds say (--set knot.closed=...)
    if tpl.parts or not tpl.layout.is_single_ring:
        rows = _system_rows(tpl, cfg, args)
    else:
        rows = _knot_rows(tpl, cfg, args)
    if out_path is not None:
        from knotmm.io.pdb import write_pdb  # noqa: PLC0415

        try:
            write_pdb(out_path, tpl.positions, layout=tpl.layout)
        except OSError as exc:
            raise TemplateError(f"--out={args.out!r} cannot be written: {exc}") from None
        layout = tpl.layout
        bonds = len(layout.bonds())
        what = ("bonds incl. the ring closure" if layout.is_single_ring
                else f"bonds; {layout.n_chains} PDB chain{'s' if layout.n_chains > 1 else ''}")
        rows.append(("wrote", f"{out_path} ({tpl.n_beads} beads, {bonds} {what}, Angstrom)"))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"{key:<{width}}  {value}", file=out)
    return 0


def _bond_row(check, cfg) -> tuple[str, str]:
    return (
        "bonds",
        f"{check.bond_min:.4f} - {check.bond_max:.4f} d (mean {check.bond_mean:.4f}; "
        f"model.bond_length {cfg['model.bond_length']:g}; largest deviation "
        f"{100 * check.bond_error:.3f}%)",
    )


def _system_rows(tpl, cfg, args) -> list[tuple[str, str]]:
    """The report of a link, an open filament or several chains: one row per chain, the
    linking numbers, the closest approach of two chains."""
    import numpy as np  # noqa: PLC0415

    from knotmm.shapes.assembly import closest_between  # noqa: PLC0415

    layout = tpl.layout
    rows = [("system", tpl.description), ("beads", f"{tpl.n_beads} in {layout.n_chains} "
                                                  f"chain{'s' if layout.n_chains > 1 else ''}")]
    slices = layout.slices()
    for k, (cid, sl, ring) in enumerate(zip(layout.ids, slices, layout.closed, strict=True)):
        x = tpl.positions[sl]
        part = tpl.parts[k] if tpl.parts else None
        bonds = np.linalg.norm(np.diff(np.vstack([x, x[:1]]) if ring else x, axis=0), axis=1)
        kt = part.knot_type if part is not None else None
        text = (f"{x.shape[0]} beads, {'closed' if ring else 'open'}; bonds "
                f"{bonds.min():.4f} - {bonds.max():.4f} d")
        if ring:
            text += "; knot type " + (kt if kt else "not checked")
        rows.append((f"chain {cid}", text))
    numbers = tpl.chain_facts.get("linking_numbers")
    if numbers:
        rows.append(("linking", ", ".join(f"{pair}: {v:+d}" if v else f"{pair}: 0"
                                          for pair, v in numbers.items())
                     + " (Gauss integral)"))
    if len(slices) > 1:
        best = min((closest_between(tpl.positions[a], tpl.positions[b])[0], i, j)
                   for i, a in enumerate(slices) for j, b in enumerate(slices) if i < j)
        rows.append(("closest", f"chains {layout.ids[best[1]]} and {layout.ids[best[2]]}, "
                                f"{best[0]:.4f} d apart"))
    rows.extend(("note", note) for note in tpl.notes if not note.startswith("knot type not")
                and not (note.startswith("knot.beads=") and args.beads is None))
    return rows


def _knot_rows(tpl, cfg, args) -> list[tuple[str, str]]:
    """The report of one closed knot."""
    check = tpl.check
    n = tpl.n_beads
    rows = [("knot", tpl.description), ("beads", str(n))]
    if "knot.major_radius" in tpl.resolved:
        rows.append(
            (
                "torus",
                f"major radius {tpl.resolved['knot.major_radius']:.4f} d, minor radius "
                f"{cfg['knot.minor_radius']:g} d",
            )
        )
    rows.append(_bond_row(check, cfg))
    i, j = check.closest_pair
    rows.append(
        (
            "closest",
            f"beads {i} and {j}, {check.min_distance:.4f} d apart (not bonded; steric range "
            f"{check.steric_range:.4f} d)",
        )
    )
    rows.append(("writhe", f"{tpl.writhe:+.4f}"))
    if tpl.knot_type is None:
        rows.append(("knot type", "not checked: topoly not installed (pip install topoly)"))
    else:
        rows.append(("knot type", f"{tpl.knot_type} (topoly, HOMFLY-PT polynomial)"))
    for note in tpl.notes:
        if note.startswith("knot type not checked"):
            continue
        if note.startswith("knot.beads=") and args.beads is None:
            continue  # the file's bead count, not one the user asked for
        rows.append(("note", note))
    return rows
