"""One style for every figure knotmm writes: axis labels with units, plain tick labels.

:data:`LABELS` maps run-file keys (``knot.beads``, ``model.bending_stiffness``) and the
quantities the analysis, sweeps and orbits report (``tau_swirl``, ``rho0``, ...) to
mathtext labels with their model units (d, F0, tau_d); :func:`label` looks one up (an
unknown key is returned as it is). :func:`plain_ticks` turns off matplotlib's offset and
scientific notation on linear axes (no ``+1.19e1`` above an axis), and
:func:`integer_ticks` puts ticks on whole numbers only (replicas, bead counts).
"""

from __future__ import annotations

__all__ = ["LABELS", "integer_ticks", "label", "plain_ticks"]

#: Key or quantity -> axis label (mathtext, units in brackets).
LABELS: dict[str, str] = {
    # run-file keys
    "knot.beads": r"beads $N$",
    "knot.p": r"torus winding $p$",
    "knot.q": r"torus winding $q$",
    "knot.minor_radius": r"template minor radius $a$ [$d$]",
    "knot.major_radius": r"template major radius $R$ [$d$]",
    "knot.perturbation": r"template perturbation [$d$]",
    "model.bending_stiffness": r"bending stiffness $A$ [$F_0 d$]",
    "model.bond_stiffness": r"bond stiffness $B$ [$F_0/d$]",
    "model.bond_length": r"bond length $l_0$ [$d$]",
    "model.lj_epsilon": r"steric energy $\epsilon$ [$F_0 d$]",
    "model.lj_sigma": r"steric range $\sigma$ [$d$]",
    "run.peclet": r"Péclet number $Pe$",
    "run.seed": "seed",
    "point": "point",
    "replica": "replica",
    # quantities
    "time": r"$t$ [$\tau_d$]",
    "tau_swirl": r"$\tau_{swirl}$ [$\tau_d$]",
    "tau_rot": r"$\tau_{rot}$ [$\tau_d$]",
    "tau_sed": r"$\tau_{sed}$ [$\tau_d$]",
    "period": r"period $T$ [$\tau_d$]",
    "velocity": r"$V$ [$d/\tau_d$]",
    "rho0": r"$\rho_0$ [$d$]",
    "swirl_amplitude": r"$C$ [$d$]",
    "frequency": r"frequency [$1/\tau_d$]",
    "multiplier_re": r"Re $\mu$",
    "multiplier_im": r"Im $\mu$",
    "multiplier_abs": r"$|\mu|$",
    "exponent": r"Floquet exponent $\ln|\mu|/T$ [$1/\tau_d$]",
    "rotation_per_period": r"rotation per period $\theta$ [rad]",
}


def label(key: str) -> str:
    """The axis label of a run-file key or quantity (the key itself when unknown)."""
    return LABELS.get(key, key)


def plain_ticks(ax) -> None:
    """No offset (``+1.19e1``) and no scientific notation on the linear axes of ``ax``."""
    from matplotlib.ticker import ScalarFormatter

    for axis in (ax.xaxis, ax.yaxis):
        formatter = axis.get_major_formatter()
        if isinstance(formatter, ScalarFormatter):
            formatter.set_useOffset(False)
            formatter.set_scientific(False)


def integer_ticks(axis) -> None:
    """Ticks on whole numbers only (an ``ax.xaxis`` or ``ax.yaxis``)."""
    from matplotlib.ticker import MaxNLocator

    axis.set_major_locator(MaxNLocator(integer=True))
