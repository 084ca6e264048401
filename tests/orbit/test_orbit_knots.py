"""Orbits of other knots (slow): the mirror image and T(2,5).

A reflection in a vertical plane maps the model onto itself (gravity stays along -z), so the
left-handed trefoil's orbit must be the mirror image of the right-handed one's: the same
period, speed and multipliers, the opposite rotation. This holds whatever the orbit is, so it
checks the whole chain (template, run, analysis, shooting, Arnoldi) against an invariant.
"""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.slow


def _orbit(run_dir, modes=4):
    from knotmm.orbit.driver import orbit_of_run

    return orbit_of_run(run_dir, modes=modes, out=run_dir / "orbit").summary


def test_mirrored_trefoil_has_the_mirror_orbit(run40, tmp_path, run_maker):
    right = _orbit(run40)
    left = _orbit(run_maker(tmp_path / "left", **{"knot.mirror": True}))
    assert left["status"] == right["status"] == "converged"
    assert left["period"] == pytest.approx(right["period"], rel=1e-6)
    assert left["rotation_per_period"] == pytest.approx(-right["rotation_per_period"],
                                                        rel=1e-5)
    assert left["sedimentation_velocity"] == pytest.approx(right["sedimentation_velocity"],
                                                           rel=1e-6)
    # the multipliers of the fixed-step map depend on the phase the orbit was started from
    # at O(h^2) (3e-4 at h = 0.01 tau_d): compare them at that accuracy
    np.testing.assert_allclose(left["floquet_moduli"], right["floquet_moduli"], rtol=1e-3)
    assert left["leading_mode_shape"]["label"] == right["leading_mode_shape"]["label"]


def test_t25_orbit_converges_and_matches_its_run(tmp_path, run_maker):
    run_dir = run_maker(tmp_path / "t25", **{"knot.q": 5, "knot.beads": 60,
                                             "run.duration": 80.0})
    s = _orbit(run_dir)
    assert s["status"] == "converged"
    assert s["residual"] <= 1e-8
    assert s["period"] == pytest.approx(s["run_tau_swirl"], rel=2e-3)
    assert len(s["floquet_multipliers"]) == 4
