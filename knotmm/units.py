"""Model units and how OpenMM and trajectory files read them.

knotmm works in model units everywhere in its API:

* length: the bead diameter ``d``
* force: ``F0``, the gravitational force on one bead
* time: ``tau_d = d / (mu0 F0)``, the time a lone bead takes to fall one diameter
* energy: ``F0 d``
* mobility: ``mu0 = 1 / (3 pi eta d)``, the single-bead mobility

Inside OpenMM 1 d reads as 1 nm, 1 F0 d as 1 kJ/mol and 1 tau_d as 1 ps, so forces come back
in kJ/mol/nm = F0 and no conversion factor appears in the engine. Files that carry lengths in
Angstrom (DCD, PDB) show a bead diameter of 10 A: the conversion happens once, at the file
boundary.
"""

from __future__ import annotations

import math

from knotmm.errors import ConfigError

#: Angstrom per bead diameter in DCD and PDB files (1 d = 1 nm = 10 A).
ANGSTROM_PER_D = 10.0
#: nm per bead diameter inside OpenMM.
NM_PER_D = 1.0
#: Angstrom per nm: mdtraj, as OpenMM, holds lengths in nm and reads and writes files in A.
ANGSTROM_PER_NM = ANGSTROM_PER_D / NM_PER_D
#: ps per tau_d inside OpenMM.
PS_PER_TAU = 1.0
#: kJ/mol per F0 d inside OpenMM.
KJMOL_PER_F0D = 1.0
#: Steric range factor: the truncated Lennard-Jones acts for r < 2**(1/6) sigma.
LJ_CUTOFF_FACTOR = 2.0 ** (1.0 / 6.0)


def d_to_angstrom(x):
    """Convert lengths in bead diameters to Angstrom (for DCD/PDB files)."""
    return x * ANGSTROM_PER_D


def angstrom_to_d(x):
    """Convert lengths in Angstrom (from DCD/PDB files) to bead diameters."""
    return x / ANGSTROM_PER_D


def d_to_mdtraj(x):
    """Lengths in d as an mdtraj Trajectory holds them (nm), for writing Angstrom files.

    Converted through Angstrom (``x * 10 * 0.1``, not ``x * NM_PER_D``): the rounding every
    knotmm PDB has been written with, so a file written again is the same file.
    """
    return d_to_angstrom(x) * (1.0 / ANGSTROM_PER_NM)


def mdtraj_to_angstrom(x):
    """Lengths of an mdtraj Trajectory (nm) in Angstrom, as its file holds them."""
    return x * ANGSTROM_PER_NM


def thermal_energy(peclet: float) -> float:
    """``kT = F0 d / Pe`` in F0 d (model units); 0 for ``Pe = inf``.

    Raises
    ------
    ConfigError
        For ``Pe <= 0`` or NaN.
    """
    peclet = float(peclet)
    if not peclet > 0:  # also NaN
        raise ConfigError(f"run.peclet = {peclet!r}: must be > 0 (inf: deterministic)")
    return 0.0 if math.isinf(peclet) else 1.0 / peclet
