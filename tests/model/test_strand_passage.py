"""Strand passage: the study's bead model allows it under pressure; segment_repulsion forbids it.

The experiment: a right-handed trefoil is pulled by harmonic springs towards its own mirror
image (z -> -z). Reaching the mirror image needs every crossing to switch, i.e. strands must
pass through each other. The outcome is judged independently by topoly's chiral knot
identification and by the sign of the writhe (a closed-form Gauss integral).
"""

import numpy as np
import openmm
import pytest

from knotmm.dynamics.registry import make
from knotmm.engine.simulation import Simulation
from knotmm.knots.identify import identify_knot, topoly_available
from knotmm.knots.writhe import writhe
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system, site_positions
from knotmm.shapes import torus_knot

pytestmark = pytest.mark.skipif(not topoly_available(), reason="needs topoly")


def _pull_to_mirror(segment_repulsion: bool, duration: float = 5.0):
    start = torus_knot(2, 3, 48)
    start = start - start.mean(axis=0)
    target = start * np.array([1.0, 1.0, -1.0])
    model = ChainModel(gravity=0.0, segment_repulsion=segment_repulsion)
    sim = Simulation(start, model, make("rk23", 0.01, tolerance=1e-4), platform="CPU")
    spring = openmm.CustomExternalForce("0.5*k_pull*((x-x0)^2+(y-y0)^2+(z-z0)^2)")
    spring.addGlobalParameter("k_pull", 5.0)
    for name in ("x0", "y0", "z0"):
        spring.addPerParticleParameter(name)
    for i, p in enumerate(target):
        spring.addParticle(i, [float(v) for v in p])
    sim.system.addForce(spring)
    sim.context.reinitialize(preserveState=True)
    assert identify_knot(sim.positions, chiral=True) == "+3_1"
    assert writhe(sim.positions) > 2.5
    sim.run(duration)
    return sim


def test_default_model_lets_strands_pass():
    sim = _pull_to_mirror(segment_repulsion=False)
    assert identify_knot(sim.positions, chiral=True) == "-3_1"
    assert writhe(sim.positions) < -2.5


def test_segment_repulsion_keeps_the_knot():
    sim = _pull_to_mirror(segment_repulsion=True)
    assert identify_knot(sim.positions, chiral=True) == "+3_1"
    assert writhe(sim.positions) > 2.5
    assert np.max(sim.bond_lengths()) < 0.7


def test_midpoint_sites_follow_their_bonds_and_carry_no_force():
    x = torus_knot(2, 3, 40)
    model = ChainModel(segment_repulsion=True)
    system = chain_system(x, model)
    assert system.getNumParticles() == 80
    for k in range(40):
        assert system.isVirtualSite(40 + k)
        assert system.getParticleMass(40 + k).value_in_unit(openmm.unit.dalton) == 0.0
    full = site_positions(x, model, ChainLayout.ring(40))
    np.testing.assert_allclose(full[40:], 0.5 * (x + np.roll(x, -1, axis=0)))


def test_midpoint_sites_do_not_change_an_uncrossed_chain():
    """On a relaxed torus no midpoint comes within the steric range of a non-excluded site,
    so both models give the same forces."""
    x = torus_knot(2, 3, 90)
    plain = Simulation(x, ChainModel(), platform="Reference")
    sites = Simulation(x, ChainModel(segment_repulsion=True), platform="Reference")
    np.testing.assert_allclose(sites.forces(x), plain.forces(x), atol=1e-9)


def _naive_site_forces(y, eps=0.25, sig=0.5):
    """Extra forces of the midpoint sites, summed pair by pair from docs/model.md's LJ form.

    Sites: beads 0..n-1 and midpoints n..2n-1 (midpoint k between beads k and k+1). Pairs
    with at least one midpoint interact unless excluded (a midpoint with beads k-1..k+2
    and with the neighbouring midpoints); a midpoint's force goes half to each of its beads.
    """
    n = len(y)
    sites = np.concatenate([y, 0.5 * (y + np.roll(y, -1, axis=0))])
    rc = 2 ** (1 / 6) * sig
    out = np.zeros_like(y)

    def owners(s):
        return [(s, 1.0)] if s < n else [(s - n, 0.5), ((s - n + 1) % n, 0.5)]

    def excluded(a, b):
        if a < n and b < n:
            return True  # bead-bead pairs belong to the plain model
        if a >= n and b >= n:
            return (a - n - (b - n)) % n in (1, n - 1) or a == b
        m, bead = (a - n, b) if a >= n else (b - n, a)
        return (bead - m) % n in (0, 1, 2, n - 1)

    for a in range(2 * n):
        for b in range(a + 1, 2 * n):
            if excluded(a, b):
                continue
            d = sites[a] - sites[b]
            r = np.linalg.norm(d)
            if r >= rc:
                continue
            f = eps * (12 * sig**12 / r**13 - 6 * sig**6 / r**7) * d / r
            for i, w in owners(a):
                out[i] += w * f
            for i, w in owners(b):
                out[i] -= w * f
    return out


def test_midpoint_repulsion_matches_a_naive_site_sum():
    """Bond (0, 1) moved to cross bond (45, 46) at right angles, 0.4 d above it."""
    x = torus_knot(2, 3, 90)
    sim_plain = Simulation(x, ChainModel(), platform="Reference")
    sim_sites = Simulation(x, ChainModel(segment_repulsion=True), platform="Reference")
    y = x.copy()
    mid = 0.5 * (y[45] + y[46])
    t = (y[46] - y[45]) / np.linalg.norm(y[46] - y[45])
    up = np.array([0.0, 0.0, 1.0])
    side = np.cross(t, up)
    y[0] = mid + 0.4 * up - 0.3 * side
    y[1] = mid + 0.4 * up + 0.3 * side
    extra = sim_sites.forces(y) - sim_plain.forces(y)
    expected = _naive_site_forces(y)
    assert np.abs(expected).max() > 10.0  # the crossing is really felt
    np.testing.assert_allclose(extra, expected, atol=1e-6)


class _FakeSim:
    def __init__(self):
        self.positions = np.zeros((4, 3))
        self.time = 0.0
        self.currentStep = 0


def test_knot_watch_records_and_stops_on_a_change():
    from knotmm.engine.reporters import KnotTypeWatch
    from knotmm.errors import KnotTypeChanged

    answers = iter(["+3_1", "unknown", "-3_1"])
    watch = KnotTypeWatch(10.0, expected="+3_1", identify=lambda x: next(answers),
                          first_index=1)
    sim = _FakeSim()
    for t in (10.0, 20.0, 30.0):
        assert watch.next_report_time(sim) == t
        sim.time = t
        watch.report(sim, None)
    assert watch.changes == [(30.0, "+3_1", "-3_1")]
    assert watch.checks == 3

    stop = KnotTypeWatch(10.0, expected="+3_1", on_change="stop", identify=lambda x: "0_1")
    with pytest.raises(KnotTypeChanged, match="from \\+3_1 to 0_1"):
        stop.report(sim, None)


def test_knot_watch_closing_without_waiting_drops_unfinished_checks():
    """An interrupted run ends at once: finished checks are judged, unfinished ones dropped."""
    from concurrent.futures import Future

    from knotmm.engine.reporters import KnotTypeWatch

    class Worker:
        def __init__(self):
            self.futures = []
            self.closed = False

        def submit(self, positions):
            self.futures.append(Future())
            return self.futures[-1]

        def close(self):
            self.closed = True

    worker = Worker()
    watch = KnotTypeWatch(10.0, expected="+3_1", identify=worker, first_index=1)
    sim = _FakeSim()
    for t in (10.0, 20.0, 30.0):
        sim.time = t
        watch.report(sim, None)
    worker.futures[0].set_result("-3_1")  # the first check is back, the others are not
    watch.close(wait=False)
    assert worker.closed
    assert watch.changes == [(10.0, "+3_1", "-3_1")]
    assert (watch.checks, watch.dropped) == (1, 2)


def test_isolated_identifier_names_a_trefoil_and_its_mirror():
    from knotmm.knots.worker import IsolatedKnotIdentifier

    identify = IsolatedKnotIdentifier(chiral=True)
    try:
        assert identify(torus_knot(2, 3, 60)) == "+3_1"
        assert identify(torus_knot(2, 3, 60, mirror=True)) == "-3_1"
    finally:
        identify.close()


def test_identifier_worker_exits_when_its_parent_is_killed(tmp_path):
    """A run killed with SIGKILL must not leave its knot-identification worker behind."""
    import os
    import queue
    import signal
    import subprocess
    import sys
    import threading
    import time

    script = tmp_path / "parent.py"
    script.write_text(
        "import sys, time\n"
        "from knotmm.knots.worker import IsolatedKnotIdentifier\n"
        "from knotmm.shapes import torus_knot\n"
        "if __name__ == '__main__':\n"
        "    ident = IsolatedKnotIdentifier()\n"
        "    print(ident(torus_knot(2, 3, 40)), flush=True)\n"
        "    print(ident._worker._proc.pid, flush=True)\n"
        "    time.sleep(60)\n"
    )
    # stderr: the killed parent's semaphore tracker complains about what it leaves behind
    parent = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    lines = queue.Queue()
    threading.Thread(
        target=lambda: [lines.put(line) for line in parent.stdout], daemon=True
    ).start()
    try:
        assert lines.get(timeout=120).strip() == "+3_1"
        # One line per print, flushed: the pid arrives whole (a file could be read half written).
        worker = int(lines.get(timeout=60))
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        # An exited child of a dead parent may linger as a zombie until it is reaped.
        try:
            with open(f"/proc/{pid}/stat") as fh:
                return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
        except FileNotFoundError:
            return False

    deadline = time.monotonic() + 10
    while alive(worker):
        if time.monotonic() > deadline:
            os.kill(worker, signal.SIGKILL)
            pytest.fail("the worker outlived its parent by 10 s")
        time.sleep(0.1)
