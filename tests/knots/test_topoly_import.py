"""The knot worker's light import of topoly (its plotting dependencies stood in for): the
knot types it names against curves whose types are known, and its two ways back to a full
import. Each case runs in a fresh interpreter, as the worker does."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from knotmm.knots.identify import topoly_available

pytestmark = pytest.mark.skipif(not topoly_available(), reason="needs topoly")

#: Parametric curves of known type (closed, 90 points): the trefoil sin t + 2 sin 2t ... and
#: its mirror image, the figure-eight knot as a Lissajous-like curve, a Hopf link of two
#: unit circles through each other's centres, and the torus knot T(2, 5).
CURVES = """
    import numpy as np
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    trefoil = np.c_[np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t),
                    -np.sin(3 * t)]
    mirror = trefoil * [1, 1, -1]
    figure_eight = np.c_[(2 + np.cos(2 * t)) * np.cos(3 * t),
                         (2 + np.cos(2 * t)) * np.sin(3 * t), np.sin(4 * t)]
    s = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    hopf = np.r_[np.c_[np.cos(s), np.sin(s), 0 * s], np.c_[1 + np.cos(s), 0 * s, np.sin(s)]]
    r = 2 + np.cos(5 * t)
    t25 = np.c_[r * np.cos(2 * t), r * np.sin(2 * t), np.sin(5 * t)]
"""


def _in_a_fresh_interpreter(code: str) -> list[str]:
    """Run ``code`` in a new Python (topoly and matplotlib not imported yet); its stdout."""
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(CURVES) + textwrap.dedent(code)],
        stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=180,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_the_light_import_names_known_knots_and_links_without_loading_matplotlib():
    out = _in_a_fresh_interpreter("""
        import sys
        from knotmm.knots import homfly
        assert homfly.preload()
        names = [homfly.identify_here(trefoil, chiral=True),
                 homfly.identify_here(mirror, chiral=True),
                 homfly.identify_here(figure_eight), homfly.identify_here(t25),
                 homfly.identify_here(hopf, components=[40, 40])]
        print(*names)
        print(getattr(sys.modules["topoly"], "_knotmm_light", False))
        print(any(n.startswith(("matplotlib", "mpl_toolkits", "scipy.ndimage",
                                "scipy.interpolate", "scipy.special")) for n in sys.modules))
    """)
    # the two trefoils are mirror images, so their signs differ (topoly's convention)
    assert sorted(out[:2]) == ["+3_1", "-3_1"]
    assert out[2:5] == ["4_1", "5_1", "L2a1"]
    assert out[5:] == ["True", "False"]  # still light after the calls; nothing heavy loaded


def test_the_stand_ins_leave_no_trace_for_later_imports():
    """After the light import, scipy.ndimage and matplotlib import for real."""
    out = _in_a_fresh_interpreter("""
        import scipy
        from knotmm.knots.topoly_import import import_topoly
        import_topoly()
        print(hasattr(scipy, "ndimage") and not callable(
            getattr(scipy.ndimage, "gaussian_filter", None)))
        import scipy.ndimage
        import matplotlib
        print(scipy.ndimage.gaussian_filter(np.eye(3), 0.0).trace())
        print(type(matplotlib.rcParams).__name__)
    """)
    assert out == ["False", "3.0", "RcParams"]


def test_a_call_that_reaches_a_stand_in_is_repeated_with_topoly_in_full():
    """A topoly whose HOMFLY-PT call draws (as a later version might) ends in StandInUsed
    in the light import; the call is repeated with the real matplotlib, and its name is
    the right one."""
    out = _in_a_fresh_interpreter("""
        import sys
        from knotmm.knots import homfly
        from knotmm.knots.topoly_import import StandInUsed, import_topoly
        light = import_topoly()
        real_homfly = light.homfly
        def drawing_homfly(*args, **kwargs):
            light.graph.plt.figure()
            return real_homfly(*args, **kwargs)
        light.homfly = drawing_homfly
        try:
            drawing_homfly(trefoil.tolist())
        except StandInUsed:
            print("stand-in-used")
        print(homfly.identify_here(figure_eight))
        print(getattr(sys.modules["topoly"], "_knotmm_light", False))
        print(type(sys.modules["matplotlib.pyplot"]).__name__)
    """)
    assert out == ["stand-in-used", "4_1", "False", "module"]


def test_a_light_import_that_fails_falls_back_to_the_full_import():
    out = _in_a_fresh_interpreter("""
        import sys
        from knotmm.knots import topoly_import
        def broken(self, module):
            raise RuntimeError("a stand-in that cannot be made")
        topoly_import._StandInFinder.exec_module = broken
        from knotmm.knots import homfly
        assert homfly.preload()
        print(getattr(sys.modules["topoly"], "_knotmm_light", False))
        print("matplotlib.pyplot" in sys.modules)
        print(homfly.identify_here(trefoil))
    """)
    assert out == ["False", "True", "3_1"]
