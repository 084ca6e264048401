"""``knotmm movie`` of several chains and of an open chain (issue 34, "Drawing"): only bonds
are drawn, a colour per chain, a title naming the system; read back from the frame's
figure and compared with bonds computed here from the chain lengths and closed flags."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from drawn_segments import (  # noqa: E402
    allowed_pairs,
    drawn_pairs,
    system_positions,
    write_system_run,
)

from knotmm.analysis import load_run  # noqa: E402
from knotmm.model.layout import ChainLayout  # noqa: E402
from knotmm.movie import _title, make_movie, render_frames, still  # noqa: E402

SYSTEMS = {
    "ring and open chain": ((30, 20), (True, False)),
    "open filament": ((60,), (False,)),
    "two rings": ((24, 18), (True, True)),
}


@pytest.fixture(scope="module", params=list(SYSTEMS))
def system(request, tmp_path_factory):
    lengths, closed = SYSTEMS[request.param]
    x = system_positions(n_frames=6, lengths=lengths, closed=closed)
    run = write_system_run(tmp_path_factory.mktemp("movie"), x, ChainLayout(lengths, closed),
                           0.5)
    return lengths, closed, run


def test_a_movie_frame_draws_only_the_bonds_of_the_layout(system):
    lengths, closed, run = system
    data = load_run(run)
    frame = 3
    fig = still(data, frame, tracer=len(data.positions[0]) - 1, dpi=40)
    x = data.positions[frame]
    drawn = drawn_pairs(fig, x - x.mean(axis=0))
    allowed = allowed_pairs(lengths, closed)
    assert drawn - allowed == set(), f"segments that are no bond: {sorted(drawn - allowed)}"
    assert drawn == allowed


def test_a_movie_colours_by_chain_and_names_the_system(system):
    lengths, closed, run = system
    data = load_run(run)
    fig = still(data, 0, dpi=40)
    top = fig.axes[2]
    bead_lines = [line for line in top.get_lines() if line.get_marker() == "o"
                  and len(line.get_xdata()) > 1]
    assert [len(line.get_xdata()) for line in bead_lines] == list(lengths)
    colours = {matplotlib.colors.to_hex(line.get_color()) for line in bead_lines}
    assert len(colours) == len(lengths)
    title = _title(data)
    if len(lengths) == 1:
        assert title == f"open filament, N = {lengths[0]}"
    else:
        for cid, n, ring in zip("AB", lengths, closed, strict=True):
            assert f"{cid}: {n} beads, {'ring' if ring else 'open'}" in title


def test_a_ring_movie_frame_is_unchanged_without_a_layout():
    """One ring: the frames drawn with its layout equal those drawn as before (no layout)."""
    x = system_positions(n_frames=3, lengths=(30,), closed=(True,))
    times = np.arange(3) * 0.5
    old = list(render_frames(x, times, dpi=30, title="T(2,3), N = 30"))
    new = list(render_frames(x, times, dpi=30, title="T(2,3), N = 30",
                             layout=ChainLayout.ring(30)))
    assert all(np.array_equal(a, b) for a, b in zip(old, new, strict=True))


def test_make_movie_of_two_chains_writes_a_gif(system, tmp_path):
    lengths, _, run = system
    if len(lengths) == 1:
        pytest.skip("one system is enough")
    result = make_movie(run, out=tmp_path / "m.gif", dpi=30, progress=False)
    assert result.frames == 6 and (tmp_path / "m.gif").stat().st_size > 1000
