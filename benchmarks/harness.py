"""The shared harness of knotmm's benchmarks: interleaved repetitions, medians, templates, CLI.

Every script in ``benchmarks/`` times its cases through :func:`interleave` (each repetition
runs every case once, the order reversed every other repetition, so that slow phases of a
shared machine hit all cases alike), summarises them with :func:`summarize` (medians, and
ratios to a baseline as the median of the per-repetition ratios), takes its chains from
:func:`template` (T(2,3) at the standard sizes :data:`SIZES`), builds its command line with
:func:`parser` (``--cases``, ``--repeats``, ``--quick``, ``--out``) and writes its numbers
with :func:`save` as a JSON data file under ``benchmarks/results/``, together with the
machine, the load average and the versions (:func:`machine`).

A result file holds::

    {"benchmark": "bench_forces engines", "argv": [...], "machine": {...},
     "settings": {...}, "cases": {name: {"median": ..., "min": ..., "max": ..., "n": ...,
     "ratio": ..., "unit": ...}}, "samples": {name: [...]}, "extra": {...}}

Not part of the tests: the scripts are run on demand (``benchmarks/README.md``).
"""

from __future__ import annotations

import argparse
import ctypes
import datetime as _dt
import importlib.metadata
import importlib.util
import json
import os
import platform as _platform
import resource
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"

#: The standard chain sizes (T(2,3) templates): ``quick`` for a smoke run, ``standard`` for
#: the figures of the README, ``large`` for the O(N^2) regime.
SIZES = {"quick": (40,), "standard": (40, 90, 240), "large": (40, 90, 240, 480, 1000, 2000)}

#: Packages whose versions a result file records.
PACKAGES = ("knotmm", "openmm", "numpy", "numba", "scipy", "mdtraj", "threadpoolctl")


# -- templates ------------------------------------------------------------------------------
def template(n: int, p: int = 2, q: int = 3, **kwargs):
    """The T(p, q) template of ``n`` beads (knotmm's ``torus_knot``), shape (n, 3), in d."""
    from knotmm.shapes import torus_knot

    return torus_knot(p, q, n, **kwargs)


def load_yardstick(name: str):
    """The sibling program ``benchmarks/<name>.py`` (``numba_chain``, ``numba_brownian``) as a
    module registered under ``name`` (numba's cache looks compiled functions up by it)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


# -- timing ---------------------------------------------------------------------------------
def per_call(fn: Callable[[], object], calls: int, clock=time.perf_counter) -> float:
    """Seconds per call of ``fn`` over ``calls`` calls in a row."""
    t0 = clock()
    for _ in range(calls):
        fn()
    return (clock() - t0) / calls


def calibrate(fn: Callable[[], object], budget: float, least: int = 2,
              clock=time.perf_counter) -> int:
    """Calls of ``fn`` that take about ``budget`` seconds (``fn`` is called once to warm up)."""
    fn()
    once = per_call(fn, 2, clock)
    return max(least, int(budget / max(once, 1e-7)))


def interleave(cases: Mapping[str, Callable[[], object]], repeats: int,
               log: Callable[[str], None] | None = None) -> dict[str, list]:
    """Run every case once per repetition; the order is reversed every other repetition.

    Parameters
    ----------
    cases : mapping of name to a callable
        Each returns one sample: a number (seconds, or seconds per unit) or a dict of numbers.
    repeats : int
        Repetitions.
    log : callable, optional
        Called with one line per sample.

    Returns
    -------
    dict
        ``{name: [sample, ...]}``, ``repeats`` samples each, in the order they were taken.
    """
    names = list(cases)
    samples: dict[str, list] = {name: [] for name in names}
    for r in range(repeats):
        for name in (names if r % 2 == 0 else names[::-1]):
            value = cases[name]()
            samples[name].append(value)
            if log is not None:
                log(f"  [{r + 1}/{repeats}] {name}: {_short(value)}")
    return samples


def _short(value) -> str:
    if isinstance(value, Mapping):
        return ", ".join(f"{k} {v:.4g}" for k, v in value.items()
                         if isinstance(v, (int, float)) and not isinstance(v, bool))
    return f"{value:.4g}" if isinstance(value, (int, float)) else str(value)


def _values(samples: Sequence, key: str | None) -> list[float]:
    if key is None:
        return [float(s) for s in samples]
    return [float(s[key]) for s in samples]


def summarize(samples: Mapping[str, Sequence], baseline: str | None = None,
              key: str | None = None, unit: str = "s") -> dict[str, dict]:
    """Median, min, max of each case's samples, and its ratio to ``baseline``.

    The ratio is the median of the per-repetition ratios (the repetitions were interleaved,
    so each ratio compares samples taken under the same load), not a ratio of medians.
    ``key`` picks one number of dict samples (e.g. ``"wall"``).
    """
    out = {}
    base = _values(samples[baseline], key) if baseline in samples else None
    for name, values in samples.items():
        v = _values(values, key)
        row = {"median": statistics.median(v), "min": min(v), "max": max(v), "n": len(v),
               "unit": unit}
        if base is not None:
            row["ratio"] = statistics.median(a / b for a, b in zip(v, base, strict=False))
            row["baseline"] = baseline
        out[name] = row
    return out


def ratio(samples: Mapping[str, Sequence], num: str, den: str, key: str | None = None) -> float:
    """Median of the per-repetition ratios ``num / den``."""
    a, b = _values(samples[num], key), _values(samples[den], key)
    return statistics.median(x / y for x, y in zip(a, b, strict=False))


_libc = ctypes.CDLL(None, use_errno=True)


class Pinned:
    """The calling thread on the core it runs on now, inside ``with`` (threads it starts,
    such as OpenMM's CPU-platform pool, inherit the mask); nothing when ``on`` is false."""

    def __init__(self, on: bool = True):
        self.on = on

    def __enter__(self):
        if self.on:
            self.saved = os.sched_getaffinity(0)
            os.sched_setaffinity(0, {_libc.sched_getcpu()})
        return self

    def __exit__(self, *exc):
        if self.on:
            os.sched_setaffinity(0, self.saved)


# -- whole commands -------------------------------------------------------------------------
def knotmm_command() -> list[str]:
    """The ``knotmm`` command of this interpreter's environment."""
    exe = Path(sys.executable).parent / "knotmm"
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("knotmm")
    return [found] if found else [sys.executable, "-m", "knotmm.cli"]


def timed(cmd: Sequence[str], env: Mapping[str, str] | None = None,
          timeout: float | None = None) -> dict:
    """Run ``cmd``: wall seconds, the children's CPU seconds (user + system), the return
    code (``"timeout"`` when stopped after ``timeout`` s) and the last line of its output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(list(cmd), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=None if env is None else dict(env))
    try:
        out, _ = proc.communicate(timeout=timeout)
        rc = proc.returncode
        wall = time.perf_counter() - t0
    except subprocess.TimeoutExpired:
        wall = time.perf_counter() - t0
        proc.terminate()  # knotmm stops after the current step and keeps its files
        try:
            out, _ = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
        rc = "timeout"
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = [ln for ln in (out or "").splitlines() if ln.strip()]
    return {"wall": wall, "cpu": cpu, "rc": rc, "last": lines[-1] if lines else ""}


def knotmm_run(out: Path, duration: float, sets: Sequence[str] = (), extra: Sequence[str] = (),
               timeout: float | None = None, check: bool = True) -> dict:
    """``knotmm run --duration D --out OUT`` with ``--set`` keys, timed by :func:`timed`."""
    cmd = [*knotmm_command(), "run", "--duration", f"{duration:g}", "--out", str(out),
           "--overwrite", "--no-progress", *extra]
    for key in sets:
        cmd += ["--set", key]
    result = timed(cmd, timeout=timeout)
    result["last"] = result["last"].replace(str(out), "OUT")  # no machine paths in results
    if check and result["rc"] not in (0, "timeout"):
        raise SystemExit(f"knotmm run failed ({' '.join(cmd[1:])}):\n{result['last']}")
    return result


def parse_variants(texts: Sequence[str], common: Sequence[str] = ()) -> list[tuple[str, list]]:
    """``NAME:KEY=VALUE[;KEY=VALUE]`` texts as ``(name, [--set keys])``; ``[("default", common)]``
    when there are none."""
    if not texts:
        return [("default", list(common))]
    out = []
    for text in texts:
        name, _, keys = text.partition(":")
        out.append((name, list(common) + [k for k in keys.split(";") if k]))
    return out


# -- the machine and the result files -------------------------------------------------------
def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return _platform.processor() or _platform.machine()


def _commit() -> str | None:
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE,
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=HERE, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+changes" if dirty else "")


def machine() -> dict:
    """The machine and software a result was measured with (no paths, no host name)."""
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return {
        "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": _cpu_model(), "cpus": os.cpu_count(),
        "affinity": len(os.sched_getaffinity(0)), "system": _platform.system(),
        "machine": _platform.machine(), "python": _platform.python_version(),
        "load_average": [round(v, 2) for v in os.getloadavg()],
        "versions": versions, "commit": _commit(),
    }


def parser(description: str, cases: Sequence[str] | None = None, repeats: int = 3,
           **kwargs) -> argparse.ArgumentParser:
    """An ``argparse`` parser with the harness's options: ``--cases`` (a subset of
    ``cases``), ``--repeats``, ``--quick`` (tiny settings, nothing saved unless ``--out``)
    and ``--out`` (the result file; default ``benchmarks/results/<name>.json``, ``-``:
    none)."""
    p = argparse.ArgumentParser(description=description, **kwargs)
    add_options(p, cases, repeats)
    return p


def add_options(p: argparse.ArgumentParser, cases: Sequence[str] | None = None,
                repeats: int = 3) -> argparse.ArgumentParser:
    """Add the harness's options (see :func:`parser`) to ``p`` (a parser or a sub-parser)."""
    if cases is not None:
        p.add_argument("--cases", nargs="+", default=list(cases), metavar="CASE",
                       help=f"cases to run (default: all of {', '.join(cases)})")
    p.add_argument("--repeats", type=int, default=repeats,
                   help=f"interleaved repetitions per median (default {repeats})")
    p.add_argument("--quick", action="store_true",
                   help="tiny settings (a smoke run of well under a minute); nothing is saved "
                        "unless --out is given")
    p.add_argument("--out", default=None,
                   help="result file (JSON); default benchmarks/results/<benchmark>.json; "
                        "'-': do not save")
    return p


def save(name: str, args: argparse.Namespace, cases: Mapping | None = None,
         samples: Mapping | None = None, extra: Mapping | None = None,
         machine_before: Mapping | None = None) -> Path | None:
    """Write one result file (see the module docstring); returns its path, or None.

    ``name`` is the benchmark (``"bench_forces engines"``); the default file is
    ``benchmarks/results/<name with _ for spaces>.json``, replaced by each full run.
    """
    out = getattr(args, "out", None)
    if out == "-" or (out is None and getattr(args, "quick", False)):
        return None
    path = Path(out) if out else RESULTS / (name.replace(" ", "_") + ".json")
    path.parent.mkdir(parents=True, exist_ok=True)
    info = dict(machine_before) if machine_before else machine()
    info["load_average_after"] = [round(v, 2) for v in os.getloadavg()]
    settings = {k: v for k, v in vars(args).items() if k not in ("out", "func", "work")}
    record = {"benchmark": name, "argv": sys.argv[1:], "machine": info, "settings": settings,
              "cases": dict(cases or {}), "samples": dict(samples or {}),
              "extra": dict(extra or {})}
    path.write_text(json.dumps(record, indent=1, default=_jsonable) + "\n")
    print(f"# results: {_display(path)}")
    return path


def _jsonable(value):
    try:
        import numpy as np

        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, np.ndarray):
            return value.tolist()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(value, Path):
        return _display(value)
    return str(value)


def _display(path: Path) -> str:
    """``path`` relative to the repository when inside it (no machine paths in the output)."""
    try:
        return str(Path(path).resolve().relative_to(HERE.parent))
    except ValueError:
        return str(path)


def cached_bytecode() -> str:
    """Let the timed programs run from compiled modules, as an installed package does.

    Where ``PYTHONDONTWRITEBYTECODE`` is set (some sandboxes and containers), an editable
    knotmm recompiles its ~100 modules in every command (0.14 s of a run, measured
    2026-12-06) while the yardsticks' modules (numpy, numba, scipy in site-packages) come
    compiled: the variable is dropped for the children and knotmm's package is compiled
    here once (``__pycache__``, ignored by git). Returns what was done, for the record.
    """
    import compileall

    if not os.environ.pop("PYTHONDONTWRITEBYTECODE", None):
        return "as the environment left it"
    spec = importlib.util.find_spec("knotmm")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        compileall.compile_dir(folder, quiet=1)  # an editable install: source and plugin
    return "compiled (PYTHONDONTWRITEBYTECODE was set: dropped for the timed programs)"


def header(args: argparse.Namespace | None = None) -> dict:
    """Print one line on the machine and return :func:`machine`'s record."""
    info = machine()
    info["bytecode"] = cached_bytecode()
    line = (f"# {info['date']}; {info['cpu']}, {info['cpus']} CPUs; load average "
            f"{' '.join(f'{v:.2f}' for v in info['load_average'])}; OpenMM "
            f"{info['versions']['openmm']}; knotmm {info['commit'] or '?'}")
    if args is not None and hasattr(args, "repeats"):
        line += f"; medians of {args.repeats} interleaved repetitions"
    print(line, flush=True)
    return info
