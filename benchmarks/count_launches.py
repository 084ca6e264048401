"""OpenCL work per step of the plugin's copies, counted: kernel launches and transfers.

A count, not a timing (issue 33's device target: how the launches grow with the number of
copies K). The script compiles a small interposer of OpenCL's enqueue calls
(``clEnqueueNDRangeKernel``, ``clEnqueueReadBuffer`` with blocking reads apart,
``clEnqueueWriteBuffer``, ``clEnqueueCopyBuffer``, ``clEnqueueFillBuffer``) with the
system's C compiler, runs itself again with it in ``LD_PRELOAD``, and steps K copies of a
T(2,3) ring of ``--beads`` beads on the OpenCL platform (double precision; the copies on a
grid, ``setCopiesApart(True)``) from the same start, so every copy takes the steps of the
single run (the copies tests hold them to it). It counts the calls of
``stepCopiesTo(t1 + T)`` after ``stepCopiesTo(t1)`` and divides by K times the single run's
accepted steps over the same interval: the work per step of one copy. K = 0 is the single
run (no copies). Linux with glibc and an OpenCL platform (pocl here) only::

    python benchmarks/count_launches.py --beads 90 --copies 0 2 8 32
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
#include <stddef.h>
typedef int cl_int; typedef unsigned int cl_uint; typedef unsigned int cl_bool;
static volatile int counting;
static long counts[6];  /* launches, reads, blocking reads, writes, copies, fills */
/* the real entry point: the next definition, or libOpenCL's (loaded by OpenMM's platform
   plugin with dlopen, so not in the global scope that RTLD_NEXT searches) */
static void* lookup(const char* name) {
    void* f = dlsym(RTLD_NEXT, name);
    if (!f) {
        void* lib = dlopen("libOpenCL.so.1", RTLD_NOW | RTLD_NOLOAD);
        if (!lib) lib = dlopen("libOpenCL.so", RTLD_NOW | RTLD_NOLOAD);
        if (lib) f = dlsym(lib, name);
    }
    return f;
}
#define NEXT(name) static void* real; if (!real) real = lookup(name)
cl_int clEnqueueNDRangeKernel(void* q, void* k, cl_uint d, const size_t* o, const size_t* g,
                              const size_t* l, cl_uint n, const void* w, void* e) {
    NEXT("clEnqueueNDRangeKernel");
    if (counting) counts[0]++;
    return ((cl_int (*)(void*, void*, cl_uint, const size_t*, const size_t*, const size_t*,
                        cl_uint, const void*, void*)) real)(q, k, d, o, g, l, n, w, e);
}
cl_int clEnqueueReadBuffer(void* q, void* b, cl_bool blocking, size_t off, size_t size,
                           void* p, cl_uint n, const void* w, void* e) {
    NEXT("clEnqueueReadBuffer");
    if (counting) { counts[1]++; if (blocking) counts[2]++; }
    return ((cl_int (*)(void*, void*, cl_bool, size_t, size_t, void*, cl_uint, const void*,
                        void*)) real)(q, b, blocking, off, size, p, n, w, e);
}
cl_int clEnqueueWriteBuffer(void* q, void* b, cl_bool blocking, size_t off, size_t size,
                            const void* p, cl_uint n, const void* w, void* e) {
    NEXT("clEnqueueWriteBuffer");
    if (counting) counts[3]++;
    return ((cl_int (*)(void*, void*, cl_bool, size_t, size_t, const void*, cl_uint,
                        const void*, void*)) real)(q, b, blocking, off, size, p, n, w, e);
}
cl_int clEnqueueCopyBuffer(void* q, void* s, void* d, size_t so, size_t dof, size_t size,
                           cl_uint n, const void* w, void* e) {
    NEXT("clEnqueueCopyBuffer");
    if (counting) counts[4]++;
    return ((cl_int (*)(void*, void*, void*, size_t, size_t, size_t, cl_uint, const void*,
                        void*)) real)(q, s, d, so, dof, size, n, w, e);
}
cl_int clEnqueueFillBuffer(void* q, void* b, const void* pat, size_t ps, size_t off,
                           size_t size, cl_uint n, const void* w, void* e) {
    NEXT("clEnqueueFillBuffer");
    if (counting) counts[5]++;
    return ((cl_int (*)(void*, void*, const void*, size_t, size_t, size_t, cl_uint,
                        const void*, void*)) real)(q, b, pat, ps, off, size, n, w, e);
}
void launches_start(void) { for (int i = 0; i < 6; i++) counts[i] = 0; counting = 1; }
void launches_stop(void) { counting = 0; }
long launches_count(int i) { return counts[i]; }
"""
KINDS = ("launches", "reads", "blocking reads", "writes", "copies", "fills")

#: (method, initial step (tau_d), tolerance (d), keyword arguments of RPYIntegrator, t1, T
#: (tau_d)): the defaults of a deterministic run and of a Brownian one at Pe = 2
CASES = [("rk23", 0.01, 1e-4, {}, 1.0, 4.0),
         ("ito_heun_adaptive", 0.001, 0.02, {"kT": 0.5, "seed": 3}, 0.2, 2.0)]


def _counted(shim, fn, *args) -> dict[str, int]:
    """The OpenCL calls of ``fn(*args)``, by kind."""
    shim.launches_start()
    fn(*args)
    shim.launches_stop()
    return {kind: shim.launches_count(i) for i, kind in enumerate(KINDS)}


def measure(beads: int, copies: list[int]) -> None:
    import numpy as np
    import openmm

    import knotmm.plugin as kp
    from knotmm.model.layout import ChainLayout
    from knotmm.model.system import chain_system
    from knotmm.shapes.geometry import torus_knot

    shim = ctypes.CDLL(None)
    shim.launches_count.restype = ctypes.c_long
    kp.use_lapack_cholesky()
    x = torus_knot(2, 3, beads)
    platform = openmm.Platform.getPlatformByName("OpenCL")
    props = {"Precision": "double"}
    print(f"OpenCL work per accepted step of one copy, N = {beads}, double precision")
    for method, h, tol, kwargs, t1, span in CASES:
        single = kp.RPYIntegrator(h, method, tol, **kwargs)
        ctx = openmm.Context(chain_system(x), single, platform, dict(props))
        ctx.setPositions(x)
        single.stepTo(t1)
        before = single.getNumAcceptedSteps()
        counted = _counted(shim, single.stepTo, t1 + span)
        steps = single.getNumAcceptedSteps() - before
        del ctx
        for k in copies:
            if k == 0:
                got, label = counted, "single run"
            else:
                integ = kp.RPYIntegrator(h, method, tol, **kwargs)
                integ.setNumCopies(k)
                integ.setCopiesApart(True)
                system = chain_system(np.vstack([x] * k),
                                      layout=ChainLayout((beads,) * k, (True,) * k))
                ctx = openmm.Context(system, integ, platform, dict(props))
                ctx.setPositions(np.vstack([x] * k))
                for c in range(k):
                    integ.setCopyPositions(c, x.ravel().tolist())
                    integ.setCopyTime(c, 0.0)
                integ.stepCopiesTo([t1] * k, 1e9)
                got = _counted(shim, integ.stepCopiesTo, [t1 + span] * k, 1e9)
                label = f"K = {k}"
                del ctx
            per = {kind: n / (max(k, 1) * steps) for kind, n in got.items()}
            print(f"  {method:18s} {label:10s} {steps} steps a copy: "
                  + ", ".join(f"{kind} {v:.2f}" for kind, v in per.items()), flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beads", type=int, default=90)
    parser.add_argument("--copies", type=int, nargs="+", default=[0, 2, 8, 32],
                        help="numbers of copies, each 0 (the single run) or at least 2")
    args = parser.parse_args(argv)
    if os.environ.get("KNOTMM_LAUNCH_SHIM"):
        measure(args.beads, args.copies)
        return 0
    return rerun_with_shim(SHIM, "launch_shim", "KNOTMM_LAUNCH_SHIM", __file__,
                           argv if argv is not None else sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
