"""identify_link: topoly's name for a link of several closed chains (issue 34), against links
whose names are known: two circles apart are a split link, two circles through each other's
disk the Hopf link L2a1."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.knots.identify import identify_link, topoly_available

T = 2 * np.pi * np.arange(30) / 30
CIRCLE = 3.0 * np.c_[np.cos(T), np.sin(T), 0 * T]


@pytest.mark.skipif(not topoly_available(), reason="topoly (knot identification) missing")
def test_known_links_get_their_names():
    assert "U" in identify_link([CIRCLE, CIRCLE + [10.0, 0.0, 0.0]])  # a split link
    hopf = CIRCLE[:, [0, 2, 1]] + [3.0, 0.0, 0.0]  # through the first circle's disk
    assert identify_link([CIRCLE, hopf]).lstrip("+-") == "L2a1"


def test_one_chain_is_no_link():
    with pytest.raises(ValueError, match="two or more chains"):
        identify_link([CIRCLE])
