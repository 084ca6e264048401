"""Heap allocations per plugin step, by the library that asked for them.

A count, not a timing: the script compiles a small ``malloc``/``calloc``/``realloc``/
``posix_memalign`` interposer with the system's C compiler, runs itself again with it in
``LD_PRELOAD``, steps a T(2,3) ring of ``--beads`` beads on each platform the plugin has a
kernel on (CPU with one thread, device platforms in double precision), and counts the
allocations of ``integ.step(250)`` minus those of ``integ.step(50)`` (the Python call's own
are the same in both), over 200 steps. Each allocation is charged to the first library on
its call stack that is not libc, libstdc++ or libgcc: ``libKnotMMRPYPlugin`` is the plugin's
step path itself; OpenMM's force evaluation (``libOpenMM``, ``libOpenMMCPU``), the OpenCL
driver (``libpocl``) and LAPACK (``openblas``) are called from it. Linux with glibc only.

    python benchmarks/count_allocations.py --beads 90
"""

from __future__ import annotations

import argparse
import ctypes
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # preload_shim.py sits here
from preload_shim import rerun_with_shim  # noqa: E402

SHIM = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <execinfo.h>
#include <stdio.h>
#include <string.h>
extern void* __libc_malloc(size_t);
extern void* __libc_calloc(size_t, size_t);
extern void* __libc_realloc(void*, size_t);
extern void* __libc_memalign(size_t, size_t);
static __thread int inside;
static volatile int counting;
#define LIBS 64
static char names[LIBS][128];
static long counts[LIBS];
static void charge(void) {
    void* frames[24];
    int n = backtrace(frames, 24);
    const char* lib = "(none)";
    for (int i = 1; i < n; i++) {
        Dl_info info;
        if (!dladdr(frames[i], &info) || !info.dli_fname) continue;
        const char* f = info.dli_fname;
        if (strstr(f, "libc.so") || strstr(f, "libstdc++") || strstr(f, "libgcc")
            || strstr(f, "alloc_shim"))
            continue;
        lib = strrchr(f, '/') ? strrchr(f, '/') + 1 : f;
        break;
    }
    for (int j = 0; j < LIBS; j++) {
        if (names[j][0] == 0) { strncpy(names[j], lib, 127); }
        if (strcmp(names[j], lib) == 0) { counts[j]++; return; }
    }
}
#define COUNT do { if (counting && !inside) { inside = 1; charge(); inside = 0; } } while (0)
void* malloc(size_t n) { void* p = __libc_malloc(n); COUNT; return p; }
void* calloc(size_t a, size_t b) { void* p = __libc_calloc(a, b); COUNT; return p; }
void* realloc(void* q, size_t n) { void* p = __libc_realloc(q, n); COUNT; return p; }
int posix_memalign(void** out, size_t a, size_t n) {
    *out = __libc_memalign(a, n); COUNT; return *out ? 0 : 12;
}
void* aligned_alloc(size_t a, size_t n) { void* p = __libc_memalign(a, n); COUNT; return p; }
void alloc_start(void) {
    memset(names, 0, sizeof names); memset(counts, 0, sizeof counts); counting = 1;
}
void alloc_stop(void) { counting = 0; }
long alloc_count(int j, char* name) {
    if (j >= LIBS || !names[j][0]) return -1;
    strcpy(name, names[j]);
    return counts[j];
}
"""

#: (method, step (tau_d), keyword arguments of RPYIntegrator)
CASES = [("rk23", 0.01, {}), ("rkc2", 0.01, {}),
         ("euler_maruyama", 0.001, {"kT": 1.0, "seed": 3}),
         ("euler_maruyama", 0.001, {"kT": 1.0, "seed": 3, "noise": "lanczos"}),
         ("ito_heun_adaptive", 0.001, {"kT": 1.0, "seed": 3}),
         ("leimkuhler_matthews", 0.01, {"kT": 1.0, "seed": 3})]


def _counts(shim) -> dict[str, int]:
    out, name = {}, ctypes.create_string_buffer(128)
    for j in range(64):
        n = shim.alloc_count(j, name)
        if n < 0:
            break
        out[name.value.decode()] = n
    return out


def measure(beads: int) -> None:
    import openmm

    import knotmm.plugin as kp
    from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
    from knotmm.model.system import chain_system
    from knotmm.shapes.geometry import torus_knot

    shim = ctypes.CDLL(None)
    shim.alloc_count.restype = ctypes.c_long
    kp.use_lapack_cholesky()
    x = torus_knot(2, 3, beads)
    print(f"allocations per step, N = {beads} (200 steps; by the library that asked)")
    for platform in plugin_platforms():
        props = ({"Precision": "double"} if platform in DEVICE_PLATFORMS
                 else {"Threads": "1"} if platform == "CPU" else {})
        for method, h, kwargs in CASES:
            integ = kp.RPYIntegrator(h, method, 1e-4, **kwargs)
            ctx = openmm.Context(chain_system(x), integ,
                                 openmm.Platform.getPlatformByName(platform), props)
            ctx.setPositions(x)
            integ.step(20)
            runs = []
            for steps in (50, 250):
                shim.alloc_start()
                integ.step(steps)
                shim.alloc_stop()
                runs.append(_counts(shim))
            per = {lib: (runs[1].get(lib, 0) - runs[0].get(lib, 0)) / 200
                   for lib in set(runs[0]) | set(runs[1])}
            own = per.pop("libKnotMMRPYPlugin.so", 0.0)
            rest = ", ".join(f"{lib} {n:.1f}" for lib, n in sorted(per.items(), key=lambda i: -i[1])
                             if n > 0)
            label = method + (" lanczos" if kwargs.get("noise") == "lanczos" else "")
            print(f"  {platform:9s} {label:27s} plugin {own:5.2f}   called from it: {rest or '-'}",
                  flush=True)
            del ctx, integ


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beads", type=int, default=90)
    args = parser.parse_args(argv)
    if os.environ.get("KNOTMM_ALLOC_SHIM"):
        measure(args.beads)
        return 0
    return rerun_with_shim(SHIM, "alloc_shim", "KNOTMM_ALLOC_SHIM", __file__,
                           argv if argv is not None else sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
