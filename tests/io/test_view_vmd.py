"""``view.vmd``: opens from any directory and follows the falling chain.

VMD is not needed: the script runs in Python's own Tcl interpreter (tkinter) with the VMD
commands it uses replaced by stand-ins that record their calls. ``vmd -e FILE`` evaluates a
file command by command (``TclTextInterp::evalFile``: ``info script`` is empty there);
``source FILE`` in VMD's console is Tcl's own.
"""

from __future__ import annotations

import os
import shutil

import pytest

from knotmm.io.rundir import TOPOLOGY_FILE, TRAJECTORY_FILE, VMD_FILE
from knotmm.io.vmd import vmd_script, write_vmd_script

#: The VMD commands view.vmd uses, recording what they are asked to do.
VMD_STANDINS = r"""
set ::calls {}
set ::frame 0
proc mol {what args} {
    lappend ::calls [list mol $what {*}$args]
    if {$what eq "new"} { return 0 }
}
proc atomselect {mol text} {
    proc ::beads {args} { lappend ::calls [list beads {*}$args] }
    return ::beads
}
proc measure {what sel} { return [list 1.5 -2.0 [expr {-10.0 * $::frame}]] }
proc molinfo {mol what args} {
    if {$what eq "get" && $args eq "frame"} { return $::frame }
    lappend ::calls [list molinfo $mol $what {*}$args]
}
proc animate {args} { global vmd_frame; set ::frame [lindex $args 1]; set vmd_frame(0) $::frame }
proc display {args} {}
proc axes {args} {}
"""


def _tcl():
    tkinter = pytest.importorskip("tkinter")
    try:
        tcl = tkinter.Tcl()
    except tkinter.TclError as exc:  # pragma: no cover - a Python without Tcl
        pytest.skip(f"no Tcl interpreter: {exc}")
    tcl.eval(VMD_STANDINS)
    return tcl


def _as_vmd_e(tcl, path) -> None:
    """Evaluate ``path`` as ``vmd -e`` does: complete commands one after the other."""
    command = ""
    for line in path.read_text().splitlines():
        command += line + "\n"
        if tcl.call("info", "complete", command):
            tcl.eval(command)
            command = ""


def _loaded(tcl) -> list[str]:
    calls = [tcl.splitlist(c) for c in tcl.splitlist(tcl.eval("set ::calls"))]
    return [c[2] for c in calls if c[0] == "mol" and c[1] in ("new", "addfile")]


def _centres(tcl) -> list[str]:
    calls = [tcl.splitlist(c) for c in tcl.splitlist(tcl.eval("set ::calls"))]
    return [tcl.splitlist(c[4])[0] for c in calls
            if c[0] == "molinfo" and c[2:4] == ("set", "center")]


def _run_dir(path):
    path.mkdir(parents=True)
    (path / TOPOLOGY_FILE).write_text("ATOM\n")
    (path / TRAJECTORY_FILE).write_bytes(b"\0")
    write_vmd_script(path, "test")
    return path


def _same(a, b) -> bool:
    return os.path.samefile(a, b)


def test_script_text_names_its_files_through_its_directory(tmp_path):
    text = vmd_script(tmp_path, "1.2.3")
    assert "knotmm 1.2.3" in text and "vmd -e RUN_DIR/view.vmd" in text
    assert f"[file join $knotmm_dir {TOPOLOGY_FILE}]" in text
    assert f"[file join $knotmm_dir {TRAJECTORY_FILE}]" in text
    assert f"mol new {TOPOLOGY_FILE}" not in text and f"mol addfile {TRAJECTORY_FILE}" not in text
    assert "[file dirname [file normalize [info script]]]" in text
    # following the chain: VMD's frame callback variable moves the molecule's centre
    assert "trace add variable vmd_frame($knotmm_mol) write knotmm_centre" in text
    assert "molinfo $knotmm_mol set center [list [measure center $knotmm_beads]]" in text
    assert "@" not in text


def test_vmd_e_from_another_directory_loads_the_run(tmp_path, monkeypatch):
    run = _run_dir(tmp_path / "runs" / "trefoil")
    monkeypatch.chdir(tmp_path)  # as in the README: vmd -e runs/trefoil/view.vmd
    tcl = _tcl()
    _as_vmd_e(tcl, run / VMD_FILE)
    pdb, dcd = _loaded(tcl)
    assert _same(pdb, run / TOPOLOGY_FILE) and _same(dcd, run / TRAJECTORY_FILE)


def test_a_moved_run_directory_opens_when_sourced_or_from_inside(tmp_path, monkeypatch):
    old = _run_dir(tmp_path / "old")
    new = tmp_path / "elsewhere" / "copy"
    new.parent.mkdir()
    shutil.move(old, new)
    monkeypatch.chdir(tmp_path)
    tcl = _tcl()
    tcl.call("source", str(new / VMD_FILE))  # VMD's console: source PATH/view.vmd
    assert _same(_loaded(tcl)[0], new / TOPOLOGY_FILE)
    monkeypatch.chdir(new)
    tcl = _tcl()
    _as_vmd_e(tcl, new / VMD_FILE)  # cd RUN_DIR; vmd -e view.vmd
    assert _same(_loaded(tcl)[0], new / TOPOLOGY_FILE)
    monkeypatch.chdir(tmp_path)
    tcl = _tcl()
    with pytest.raises(Exception, match=r"view\.vmd: no topology\.pdb and trajectory\.dcd in"):
        _as_vmd_e(tcl, new / VMD_FILE)


def test_directory_names_with_tcl_characters(tmp_path, monkeypatch):
    run = _run_dir(tmp_path / 'run [1] $x "q" {b} ;c')
    monkeypatch.chdir(tmp_path)
    tcl = _tcl()
    _as_vmd_e(tcl, run / VMD_FILE)
    assert _same(_loaded(tcl)[0], run / TOPOLOGY_FILE)


def test_the_view_follows_the_chain_frame_by_frame(tmp_path, monkeypatch):
    run = _run_dir(tmp_path / "run")
    monkeypatch.chdir(tmp_path)
    tcl = _tcl()
    _as_vmd_e(tcl, run / VMD_FILE)
    assert _centres(tcl) == ["1.5 -2.0 -0.0"]  # centred on frame 0 at once
    for frame in (1, 7):  # VMD sets vmd_frame(molid) when the frame changes
        tcl.eval(f"set ::frame {frame}; set vmd_frame(0) {frame}")
    assert _centres(tcl)[1:] == ["1.5 -2.0 -10.0", "1.5 -2.0 -70.0"]
    calls = tcl.eval("set ::calls")
    assert "beads frame 7" in calls  # the centre of the frame shown
    tcl.eval("knotmm_follow off; set ::frame 9; set vmd_frame(0) 9")
    assert len(_centres(tcl)) == 3
