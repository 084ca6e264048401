"""``view.vmd``: the VMD script of a run directory (:mod:`knotmm.io.rundir`).

``vmd -e RUN_DIR/view.vmd`` (from any directory) loads the run's topology and trajectory,
draws the chains and centres the view on them frame by frame.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from knotmm.io.rundir import TOPOLOGY_FILE, TRAJECTORY_FILE, VMD_FILE

__all__ = ["VMD_SCRIPT", "vmd_script", "write_vmd_script"]

VMD_SCRIPT = """\
# VMD script written by knotmm @VERSION@. Open it from any directory:
#     vmd -e RUN_DIR/view.vmd        or, in VMD's Tk console:  source RUN_DIR/view.vmd
# It loads topology.pdb and trajectory.dcd of its run directory and centres the view on the
# chain in every frame, so that the falling ring stays in sight (knotmm_follow off: the lab
# frame, where it falls out of view). Lengths are in Angstrom: one bead diameter d = 10 A.
proc knotmm_run_directory {recorded} {
    # source sets info script; vmd -e reads the file line by line and leaves it empty, so
    # the directory the run was written in comes next, then the current directory
    set candidates [list]
    if {[info script] ne ""} {
        lappend candidates [file dirname [file normalize [info script]]]
    }
    lappend candidates $recorded [pwd]
    foreach dir $candidates {
        set pdb [file join $dir @TOPOLOGY@]
        set dcd [file join $dir @TRAJECTORY@]
        if {[file isfile $pdb] && [file isfile $dcd]} {
            return $dir
        }
    }
    set message "view.vmd: no @TOPOLOGY@ and @TRAJECTORY@ in [join $candidates {, }]"
    append message "; open view.vmd in its run directory: cd RUN_DIR; vmd -e view.vmd"
    error $message
}
set knotmm_dir [knotmm_run_directory @RUN_DIR@]
set knotmm_mol [mol new [file join $knotmm_dir @TOPOLOGY@] type pdb waitfor all]
mol addfile [file join $knotmm_dir @TRAJECTORY@] type dcd first 0 last -1 step 1 waitfor all
set knotmm_beads [atomselect $knotmm_mol all]
$knotmm_beads global
$knotmm_beads set radius 5.0
mol delrep 0 $knotmm_mol
mol representation VDW 1.0 16
mol color ResID
mol material AOChalky
mol addrep $knotmm_mol
mol representation Bonds 2.0 12
mol color ResID
mol addrep $knotmm_mol
display projection Orthographic
axes location LowerLeft
# Follow the chain: VMD sets vmd_frame(molid) at every frame change; the trace moves the
# molecule's centre (molinfo ... set center) to the centre of the beads in that frame.
proc knotmm_centre {args} {
    global knotmm_mol knotmm_beads
    $knotmm_beads frame [molinfo $knotmm_mol get frame]
    molinfo $knotmm_mol set center [list [measure center $knotmm_beads]]
}
proc knotmm_follow {{how on}} {
    global knotmm_mol vmd_frame
    trace remove variable vmd_frame($knotmm_mol) write knotmm_centre
    if {$how eq "on"} {
        trace add variable vmd_frame($knotmm_mol) write knotmm_centre
        knotmm_centre
    }
}
animate goto 0
knotmm_follow on
"""


def _tcl_word(text: str) -> str:
    """``text`` as one Tcl word, in double quotes with Tcl's special characters escaped."""
    escaped = re.sub(r'([\\$\[\]"])', r"\\\1", str(text))
    return '"' + escaped.replace("\n", "\\n").replace("\r", "\\r").replace("\t", "\\t") + '"'


def vmd_script(directory, version: str, n_chains: int = 1) -> str:
    """The text of ``view.vmd`` for the run directory ``directory``.

    One chain is coloured along its beads (VMD's ``ResID``), several chains one colour each
    (``Chain``; past 62 chains, whose one-character PDB chain identifiers repeat, by their
    unique segment names, ``SegName``).

    The script finds its files relative to itself where VMD says where it is (``source``)
    and else in ``directory`` as written here (absolute) or the current directory
    (``vmd -e`` gives a script no name), so it works from any directory, and from a run
    directory that was moved when it is opened there.
    """
    text = VMD_SCRIPT.replace("@VERSION@", version)
    if n_chains > 1:
        by = "Chain" if n_chains <= 62 else "SegName"  # 62: one-character PDB chain ids
        text = text.replace("mol color ResID", f"mol color {by}")
    text = text.replace("@TOPOLOGY@", TOPOLOGY_FILE).replace("@TRAJECTORY@", TRAJECTORY_FILE)
    return text.replace("@RUN_DIR@", _tcl_word(os.path.abspath(directory)))


def write_vmd_script(directory, version: str, n_chains: int = 1) -> None:
    """Write ``view.vmd`` (atomically): :func:`vmd_script`."""
    from knotmm.io.atomic import write_text_atomic

    write_text_atomic(Path(directory) / VMD_FILE, vmd_script(directory, version, n_chains))
