"""What a figure writes, as a reader sees it: the size of its smallest text in pixels and the
pairs of texts whose boxes overlap (measured on the drawn figure with matplotlib's renderer,
not taken from the plotting code's settings)."""

from __future__ import annotations

__all__ = ["overlapping_texts", "smallest_text_px", "texts"]


def texts(fig):
    """The figure's drawn, non-empty texts and their boxes in pixels, after a draw.

    Tick labels are taken only for the ticks an axis draws (within its view limits; matplotlib
    keeps the labels of other ticks as texts it does not draw).
    """
    from matplotlib.text import Text

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    all_tick_labels, drawn_tick_labels = set(), set()
    for ax in fig.axes:
        for axis in ax._axis_map.values():
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                all_tick_labels |= {id(tick.label1), id(tick.label2)}
            for tick in axis._update_ticks():  # the ticks this axis draws
                drawn_tick_labels |= {id(tick.label1), id(tick.label2)}
    out = []
    for t in fig.findobj(Text):
        if not (t.get_visible() and t.get_text().strip()):
            continue
        if t.axes is not None and not t.axes.get_visible():
            continue
        if id(t) in all_tick_labels and id(t) not in drawn_tick_labels:
            continue
        box = t.get_window_extent(renderer)
        if box.width > 0 and box.height > 0:
            out.append((t, box))
    return out


def smallest_text_px(fig) -> float:
    """The smallest font size among the figure's texts, in pixels at the figure's dpi."""
    return min(t.get_fontsize() * fig.dpi / 72.0 for t, _ in texts(fig))


def overlapping_texts(fig, pad: float = 0.0) -> list[tuple[str, str]]:
    """Pairs of texts whose boxes (grown by ``pad`` pixels) overlap, by their strings."""
    items = texts(fig)
    pairs = []
    for i, (a, box_a) in enumerate(items):
        for b, box_b in items[i + 1:]:
            grown = box_a.padded(pad)
            if grown.overlaps(box_b):
                pairs.append((a.get_text(), b.get_text()))
    return pairs
