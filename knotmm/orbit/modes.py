"""A short description of a Floquet mode from its shape.

A mode ``v`` (shape ``(n_beads, 3)``, complex for a pair of complex multipliers: its real
and imaginary parts span the plane it oscillates in) is split into orthogonal parts about
the orbit state ``x`` (centroid at the origin, the torus axis along ``z``):

* **tilt**: a rigid rotation about a horizontal axis through the centroid
  (span of ``e_x x r`` and ``e_y x r``);
* what is left, the deformation, into its **out-of-plane** (``z``) part and its
  **in-plane** part, the latter into **radial** (along the bead's horizontal radius:
  breathing when uniform) and **tangential** (sliding around the torus);

each as a fraction of ``|v|^2``. Each part has its own azimuthal wavenumber: the
``m = 0 .. 6`` with the most power in ``sum_i c_i exp(-i m phi_i)``, ``c_i`` the part's
component at bead ``i`` (the vertical displacement for the tilt, which is ``m = 1`` for a
flat torus), ``phi_i`` the bead's azimuth (``m = 0``: the same at every azimuth, ``m = 1``:
one wave around). The mode's ``m`` is the wavenumber of the part its label names: of the
tilt for a ``"tilt"`` mode, of the largest deformation part otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ModeShape", "describe_mode"]


@dataclass
class ModeShape:
    """Fractions of a mode's squared norm (they add up to 1, up to the rigid motions left).

    Attributes
    ----------
    tilt, out_of_plane, radial, tangential : float
    rigid_other : float
        Translations and the rotation about ``z`` (zero for a quotient mode).
    m : int
        Azimuthal wavenumber of the part the label names (the tilt for ``"tilt"``, the
        largest deformation part otherwise).
    label : str
        ``"tilt"``, ``"breathing"``, ``"in-plane"``, ``"sliding"`` or ``"out-of-plane"``.
    wavenumbers : dict of str to int
        The wavenumber of every part (``"tilt"``, ``"out_of_plane"``, ``"radial"``,
        ``"tangential"``) that holds power.
    """

    tilt: float
    out_of_plane: float
    radial: float
    tangential: float
    rigid_other: float
    m: int
    label: str
    wavenumbers: dict = field(default_factory=dict)

    def describe(self) -> str:
        """One line, each part's wavenumber beside its own share (parts of 1 % or more).

        E.g. ``"tilt m = 1: tilt 89 % (m = 1), out-of-plane 11 % (m = 2), in-plane radial
        0 %, tangential 0 %"``.
        """
        def part(name: str, key: str, value: float) -> str:
            m = self.wavenumbers.get(key)
            wave = f" (m = {m})" if m is not None and value >= 0.005 else ""
            return f"{name} {value:.0%}{wave}".replace("%", " %")

        parts = (part("tilt", "tilt", self.tilt),
                 part("out-of-plane", "out_of_plane", self.out_of_plane),
                 part("in-plane radial", "radial", self.radial),
                 part("tangential", "tangential", self.tangential))
        return f"{self.label} m = {self.m}: {', '.join(parts)}"


def _rigid_basis(x: np.ndarray) -> np.ndarray:
    """Orthonormal basis, shape (6, 3N): tilt about x, tilt about y, then translations, spin."""
    n = x.shape[0]
    vecs = np.zeros((6, n, 3))
    vecs[0] = np.cross(np.array([1.0, 0.0, 0.0]), x)
    vecs[1] = np.cross(np.array([0.0, 1.0, 0.0]), x)
    for axis in range(3):
        vecs[2 + axis, :, axis] = 1.0
    vecs[5] = np.cross(np.array([0.0, 0.0, 1.0]), x)
    q, _ = np.linalg.qr(vecs.reshape(6, 3 * n).T)
    return q.T


def _wavenumber(values: np.ndarray, phi: np.ndarray) -> int:
    power = [float(np.sum(np.abs(values @ np.exp(-1j * m * phi)) ** 2)) for m in range(7)]
    return int(np.argmax(power))


def describe_mode(x: np.ndarray, mode: np.ndarray) -> ModeShape:
    """Split a mode into tilt and deformation parts (see the module's text).

    Parameters
    ----------
    x : ndarray, shape (n_beads, 3), in d
        The orbit state, centroid at the origin.
    mode : ndarray, shape (n_beads, 3), real or complex

    Returns
    -------
    ModeShape
    """
    x = np.asarray(x, dtype=float)
    x = x - x.mean(axis=0)
    parts = [np.real(mode), np.imag(mode)] if np.iscomplexobj(mode) else [mode]
    basis = _rigid_basis(x)
    rho = np.hypot(x[:, 0], x[:, 1])
    radial_dir = np.zeros_like(x)
    radial_dir[:, 0] = x[:, 0] / np.where(rho > 0, rho, 1.0)
    radial_dir[:, 1] = x[:, 1] / np.where(rho > 0, rho, 1.0)
    tangent_dir = np.stack([-radial_dir[:, 1], radial_dir[:, 0], np.zeros(len(x))], axis=1)
    phi = np.arctan2(x[:, 1], x[:, 0])
    total = tilt = rigid = oop = rad = tan = 0.0
    comps = {"tilt": [], "out_of_plane": [], "radial": [], "tangential": []}
    for part in parts:
        v = np.asarray(part, dtype=float).ravel()
        coef = basis @ v
        total += float(v @ v)
        tilt += float(np.sum(coef[:2] ** 2))
        comps["tilt"].append((basis[:2].T @ coef[:2]).reshape(x.shape)[:, 2])
        rigid += float(np.sum(coef[2:] ** 2))
        d = (v - basis.T @ coef).reshape(x.shape)
        r_c = np.sum(d * radial_dir, axis=1)
        t_c = np.sum(d * tangent_dir, axis=1)
        oop += float(np.sum(d[:, 2] ** 2))
        rad += float(np.sum(r_c**2))
        tan += float(np.sum(t_c**2))
        comps["out_of_plane"].append(d[:, 2])
        comps["radial"].append(r_c)
        comps["tangential"].append(t_c)
    if total == 0:
        return ModeShape(0.0, 0.0, 0.0, 0.0, 0.0, 0, "none", {})
    fractions = {"out_of_plane": oop / total, "radial": rad / total,
                 "tangential": tan / total}
    largest = max(fractions, key=fractions.get)
    power = {"tilt": tilt / total, **fractions}
    wavenumbers = {key: _wavenumber(np.array(comps[key]), phi)
                   for key, share in power.items() if share > 1e-12}
    m = wavenumbers.get(largest, 0)
    if tilt / total >= 0.5:
        label = "tilt"
        m = wavenumbers["tilt"]
    elif largest == "radial":
        label = "breathing" if m == 0 else "in-plane"
    elif largest == "tangential":
        label = "sliding"
    else:
        label = "out-of-plane"
    return ModeShape(tilt / total, fractions["out_of_plane"], fractions["radial"],
                     fractions["tangential"], rigid / total, m, label, wavenumbers)
