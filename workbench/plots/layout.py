"""Figure layout in one pass: the axes of a figure's grid placed with margins computed from their texts.

:class:`FittedMargins` is a matplotlib layout engine (``plt.subplots(..., layout=FittedMargins())``).
When the figure is drawn (saved, or shown by the dashboard) it measures, once, how far each
axes' texts reach outside its box: the tick labels as they will be drawn (with their rotation,
size and overhang past the ends of the axis), the axis labels, an axis' offset text, the title,
and the figure's title above the grid. The figure margins and the gaps between neighbouring
axes are then set to what the texts on either side need plus :data:`PAD_PT`, with
``subplots_adjust``. Matplotlib's constrained layout finds such margins from the bounding box of
every artist, twice, laying out the tick labels again for every axes sharing an axis (about
0.1 s of CPU per figure of the campaign); here each axis lays out its ticks once more than the
drawing itself does.

Handled: axes made on one regular grid (``subplots``, ``add_subplot``; spans allowed), legends
inside their axes, the figure title of ``fig.suptitle``. Axes placed by hand (``add_axes``)
keep their position.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import matplotlib as mpl
from matplotlib.layout_engine import LayoutEngine

PAD_PT = 4.0  # pt between a text and the figure's edge or the next axes' texts
_SIDES = ("left", "right", "bottom", "top")


def _size(text, renderer) -> tuple[float, float] | None:
    """(width, height) in pixels of a visible, non-empty text, else None."""
    if not text.get_visible() or not text.get_text():
        return None
    bb = text.get_window_extent(renderer)
    return bb.width, bb.height


@dataclass
class Reach:
    """How far an axes' texts reach beyond its box (px): ``fixed`` per side, and the overhangs past
    the ends of each axis of texts centred along it (an end tick label, a title wider than the axes),
    which depend on the axes' size: (``"x"`` or ``"y"``, position as a fraction of the axis, half-length)."""

    fixed: dict[str, float] = field(default_factory=lambda: dict.fromkeys(_SIDES, 0.0))
    along: list[tuple[str, float, float]] = field(default_factory=list)

    def sides(self, width: float, height: float) -> dict[str, float]:
        """Reach per side for an axes box of ``width`` x ``height`` px."""
        need = dict(self.fixed)
        for name, f, half in self.along:
            length, start, end = (width, "left", "right") if name == "x" else (height, "bottom", "top")
            need[start] = max(need[start], half - f * length)
            need[end] = max(need[end], f * length + half - length)
        return need


def _axis_reach(axis, renderer, reach: Reach) -> None:
    """Add what ``axis``' tick labels, label and offset text reach to ``reach``."""
    horizontal = axis.axis_name == "x"
    out_side, in_side = ("bottom", "top") if horizontal else ("left", "right")
    need = reach.fixed
    scale = renderer.points_to_pixels(1.0)
    trans = axis.get_transform()
    lo, hi = trans.transform(list(axis.get_view_interval()))
    span = (hi - lo) or 1.0
    ticks_need = {out_side: 0.0, in_side: 0.0}
    for tick in axis._update_ticks():  # the ticks the drawing shows, their labels set as drawn
        f = (float(trans.transform([tick.get_loc()])[0]) - lo) / span
        out = (tick.get_tick_padding() + tick.get_pad()) * scale
        for line, label, side in ((tick.tick1line, tick.label1, out_side), (tick.tick2line, tick.label2, in_side)):
            if line.get_visible():
                ticks_need[side] = max(ticks_need[side], tick.get_tick_padding() * scale)
            size = _size(label, renderer)
            if size is None:
                continue
            along, across = size if horizontal else size[::-1]
            ticks_need[side] = max(ticks_need[side], out + across)
            reach.along.append((axis.axis_name, f, along / 2))
    for side in (out_side, in_side):
        need[side] = max(need[side], ticks_need[side])
    size = _size(axis.label, renderer)
    if size is not None:
        side = axis.get_label_position()
        need[side] = max(need[side], ticks_need[side] + axis.labelpad * scale + (size[1] if horizontal else size[0]))
    size = _size(axis.get_offset_text(), renderer)
    if size is not None:  # x: below the tick labels at the right end; y: above the axes
        side = out_side if horizontal else "top"
        below = ticks_need[out_side] if horizontal else 0.0
        need[side] = max(need[side], below + axis.OFFSETTEXTPAD * scale + size[1])


def axes_reach(ax, renderer) -> Reach:
    """How far ``ax``'s tick labels, axis labels, offset texts and title reach beyond its box."""
    reach = Reach()
    _axis_reach(ax.xaxis, renderer, reach)
    _axis_reach(ax.yaxis, renderer, reach)
    size = _size(ax.title, renderer)
    if size is not None:  # centred above the x axis' texts on top, if it has any
        on_top = ax.xaxis.get_label_position() == "top" or ax.xaxis.get_tick_params()["labeltop"]
        pad = mpl.rcParams["axes.titlepad"] * renderer.points_to_pixels(1.0)
        reach.fixed["top"] = max(reach.fixed["top"], (reach.fixed["top"] if on_top else 0.0) + pad + size[1])
        reach.along.append(("x", 0.5, size[0] / 2))
    return reach


def fit_margins(fig) -> None:
    """Set ``fig``'s subplot parameters so that the texts around its grid of axes fit (see the module)."""
    renderer = fig._get_renderer()  # the renderer the drawing uses (savefig's, at its dpi)
    grid = [(ax, ax.get_subplotspec()) for ax in fig.axes if ax.get_visible() and ax.get_subplotspec() is not None]
    if not grid:
        return
    nrows, ncols = grid[0][1].get_gridspec().get_geometry()
    pad = renderer.points_to_pixels(PAD_PT)
    width, height = fig.bbox.width, fig.bbox.height
    for ax, _ in grid:
        if ax.get_aspect() != "auto":
            ax.apply_aspect()  # limits set for the box's shape before the tick labels are measured
    reach = [(axes_reach(ax, renderer), spec) for ax, spec in grid]
    title = getattr(fig, "_suptitle", None)  # the Text of fig.suptitle, if set
    size = None if title is None else _size(title, renderer)
    above = 0.0 if size is None else (1.0 - title.get_position()[1]) * height + size[1]
    cell_w, cell_h = width / ncols, height / nrows  # an axes' size without margins, to start from
    for _ in range(20):  # the overhangs depend on the axes' size, which the margins set: to a tenth of a pixel
        sides = [(r.sides(cell_w * len(s.colspan), cell_h * len(s.rowspan)), s) for r, s in reach]

        def most(side: str, where, sides=sides) -> float:
            return max((n[side] for n, s in sides if where(s)), default=0.0)

        left = most("left", lambda s: s.colspan.start == 0) + pad
        right = most("right", lambda s: s.colspan.stop == ncols) + pad
        bottom = most("bottom", lambda s: s.rowspan.stop == nrows) + pad
        top = most("top", lambda s: s.rowspan.start == 0) + pad + above
        wgap = max((most("right", lambda s: s.colspan.stop == c) + most("left", lambda s: s.colspan.start == c)
                    for c in range(1, ncols)), default=0.0) + pad
        hgap = max((most("bottom", lambda s: s.rowspan.stop == r) + most("top", lambda s: s.rowspan.start == r)
                    for r in range(1, nrows)), default=0.0) + pad
        last = cell_w, cell_h
        cell_w = (width - left - right - (ncols - 1) * wgap) / ncols
        cell_h = (height - bottom - top - (nrows - 1) * hgap) / nrows
        if cell_w <= 0 or cell_h <= 0:  # texts larger than the figure: leave matplotlib's defaults
            return
        if abs(cell_w - last[0]) < 0.1 and abs(cell_h - last[1]) < 0.1:
            break
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height, top=1 - top / height,
                        wspace=wgap / cell_w, hspace=hgap / cell_h)


class FittedMargins(LayoutEngine):
    """Layout engine running :func:`fit_margins` once per drawing of the figure."""

    _adjust_compatible = True
    _colorbar_gridspec = True

    def execute(self, fig) -> None:
        """Place the axes of ``fig`` (called by matplotlib when the figure is drawn)."""
        fit_margins(fig)
