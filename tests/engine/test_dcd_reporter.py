"""DCDReporter writes what OpenMM's DCDFile.writeModel writes, byte for byte."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import openmm.app
import pytest
from openmm import unit

from knotmm.engine.reporters import DCDReporter
from knotmm.model.topology import bead_topology

#: The header's second title line holds DCDFile's creation date ("Created <asctime>").
_DATE = slice(180, 260)


def _masked(data: bytes) -> bytes:
    out = bytearray(data)
    out[_DATE] = bytes(_DATE.stop - _DATE.start)
    return bytes(out)


def _frames(rng, n_frames, n_beads=13):
    """Positions in d, far from the origin and with many digits (float32 rounding matters)."""
    return [rng.normal(scale=3.0, size=(n_beads, 3)) + np.array([0.1, -7.3, -4321.987654321])
            for _ in range(n_frames)]


def _openmm_file(path, topology, frames, interval):
    with open(path, "wb") as fh:
        dcd = openmm.app.DCDFile(fh, topology, interval, firstStep=0, interval=1)
        for x in frames:
            dcd.writeModel(x * unit.nanometer)


def test_frames_equal_openmms_writer(tmp_path):
    frames = _frames(np.random.default_rng(1), 7)
    top = bead_topology(13)
    _openmm_file(tmp_path / "openmm.dcd", top, frames, 0.5)
    rep = DCDReporter(tmp_path / "ours.dcd", 0.5, top)
    for x in frames:
        rep.report(SimpleNamespace(positions=x), None)
    rep.close()
    want = (tmp_path / "openmm.dcd").read_bytes()
    got = (tmp_path / "ours.dcd").read_bytes()
    assert len(got) == len(want)
    assert _masked(got) == _masked(want)


def test_appending_equals_one_openmm_file(tmp_path):
    """A resumed run appends: 3 frames, close, reopen with append, 4 more = 7 in one go."""
    frames = _frames(np.random.default_rng(2), 7)
    top = bead_topology(13)
    _openmm_file(tmp_path / "openmm.dcd", top, frames, 0.25)
    rep = DCDReporter(tmp_path / "ours.dcd", 0.25, top)
    for x in frames[:3]:
        rep.report(SimpleNamespace(positions=x), None)
    rep.close()
    rep = DCDReporter(tmp_path / "ours.dcd", 0.25, top, append=True, first_index=3)
    for x in frames[3:]:
        rep.report(SimpleNamespace(positions=x), None)
    rep.close()
    assert _masked((tmp_path / "ours.dcd").read_bytes()) == _masked(
        (tmp_path / "openmm.dcd").read_bytes())


def test_each_frame_is_on_disk_when_report_returns(tmp_path):
    """Flushed per frame: another reader sees the header count and the frame at once."""
    from knotmm.io.dcd import dcd_layout

    top = bead_topology(13)
    rep = DCDReporter(tmp_path / "t.dcd", 1.0, top)
    for k, x in enumerate(_frames(np.random.default_rng(3), 3), start=1):
        rep.report(SimpleNamespace(positions=x), None)
        layout = dcd_layout(tmp_path / "t.dcd")
        assert (layout.claimed_frames, layout.complete_frames, layout.partial_bytes) == (k, k, 0)
    rep.close()


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_or_misshapen_frames_are_refused(tmp_path, bad):
    top = bead_topology(13)
    rep = DCDReporter(tmp_path / "t.dcd", 1.0, top)
    x = np.zeros((13, 3))
    x[4, 1] = bad
    with pytest.raises(ValueError, match="non-finite"):
        rep.report(SimpleNamespace(positions=x), None)
    with pytest.raises(ValueError, match=r"expected shape \(13, 3\)"):
        rep.report(SimpleNamespace(positions=np.zeros((12, 3))), None)
    rep.close()
