"""Figure layout in one pass (workbench/plots/layout.py): every text inside the figure, none over a
neighbour's, and no margin wider than its texts need.

The reference is matplotlib's own measure of what each axes draws (``Axes.get_tightbbox``, the
bounding box of its tick labels, axis labels, title and artists, measured after the drawing),
independent of the margins the layout computed from the tick labels before drawing.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from workbench.plots.layout import PAD_PT, FittedMargins  # noqa: E402

TOL_PX = 1.0  # text extents are whole pixels after hinting; the layout measures them unrounded


def _crowded(layout) -> plt.Figure:
    """2 x 2 axes whose texts overflow matplotlib's default margins: wide y tick labels, a two-line
    y label, long rotated x tick labels on the bottom row, titles and a figure title."""
    fig, axes = plt.subplots(2, 2, figsize=(7, 5), sharex="col", layout=layout)
    x = np.arange(6)
    for k, ax in enumerate(axes.flat):
        ax.plot(x, (k + 1) * 1.5e5 * np.sin(x), "o-", label=f"series {k}")
        ax.set_ylabel(f"panel {k}\nvalue [°/h]")
        ax.set_title(f"panel {k}: a title as long as the axes")
        ax.legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xticks(x, [f"step {i}: z-up CCW 405°/s" for i in x], rotation=60, fontsize=7)
    axes[1, 1].set_yscale("log")
    fig.suptitle("A figure title over both columns")
    return fig


def _drawn(fig):
    fig.canvas.draw()  # the layout runs as the figure is drawn
    renderer = fig.canvas.get_renderer()
    return renderer, [ax.get_tightbbox(renderer) for ax in fig.axes]


def _clipped(fig, boxes) -> list[str]:
    """Sides on which an axes' texts leave the figure."""
    W, H = fig.bbox.width, fig.bbox.height
    out = []
    for k, b in enumerate(boxes):
        out += [f"axes {k} {side}" for side, over in
                (("left", -b.x0), ("right", b.x1 - W), ("bottom", -b.y0), ("top", b.y1 - H)) if over > TOL_PX]
    return out


def test_the_check_sees_texts_cut_off_by_default_margins():
    fig = _crowded(None)
    assert _clipped(fig, _drawn(fig)[1])
    plt.close(fig)


def test_every_text_inside_the_figure_and_clear_of_its_neighbours():
    fig = _crowded(FittedMargins())
    renderer, boxes = _drawn(fig)
    assert not _clipped(fig, boxes)
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            a, b = boxes[i], boxes[j]
            overlap = min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0)
            assert min(overlap) <= TOL_PX, f"texts of axes {i} and {j} overlap"
    title = fig._suptitle.get_window_extent(renderer)
    assert all(title.y0 >= b.y1 - TOL_PX for b in boxes)  # the figure title above every axes' texts
    assert title.y1 <= fig.bbox.height + TOL_PX
    plt.close(fig)


def test_margins_are_what_the_outermost_texts_need():
    fig = _crowded(FittedMargins())
    renderer, boxes = _drawn(fig)
    pad = renderer.points_to_pixels(PAD_PT)
    W = fig.bbox.width
    left, right = min(b.x0 for b in boxes), max(b.x1 for b in boxes)
    bottom = min(b.y0 for b in boxes)
    # the pad, not more (up to a pixel: text extents are hinted), on the sides where the texts of the
    # axes are outermost; on the right the titles wider than their axes set the margin
    assert left == pytest.approx(pad, abs=TOL_PX)
    assert bottom == pytest.approx(pad, abs=TOL_PX)
    assert W - right == pytest.approx(pad, abs=TOL_PX)
    plt.close(fig)


def test_an_axes_placed_by_hand_keeps_its_place():
    fig = plt.figure(figsize=(4, 3), layout=FittedMargins())
    ax = fig.add_axes((0.3, 0.3, 0.4, 0.4))
    ax.set_ylabel("value")
    _drawn(fig)
    assert tuple(ax.get_position().bounds) == pytest.approx((0.3, 0.3, 0.4, 0.4))
    plt.close(fig)
