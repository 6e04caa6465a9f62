"""Checks a figure must pass before it is saved: no two texts overlap (tick labels, value labels,
titles, legend entries) and no legend inside an axes covers data (lines, markers, bars, bands).

Matplotlib gives every artist's extent in display pixels once the figure is drawn
(``get_window_extent``), so both checks are rectangle tests on what would be printed.
:func:`problems` lists what is wrong in words; :func:`pipeline.report.figures.save` warns with
:class:`FigureOverlapWarning` (the tests turn it into an error).
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import Collection
from matplotlib.legend import Legend
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.text import Text

TOLERANCE = 1.0  # pixels two boxes may share (antialiased edges)


class FigureOverlapWarning(UserWarning):
    """A figure with overlapping texts or a legend over its data; the message names them."""


def _texts(fig) -> list[Text]:
    hidden = set()  # labels of ticks outside the view: matplotlib does not draw them
    for ax in fig.axes:
        for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
            lo, hi = min(lo, hi), max(lo, hi)
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not lo - 1e-9 * abs(hi - lo) <= tick.get_loc() <= hi + 1e-9 * abs(hi - lo):
                    hidden |= {id(tick.label1), id(tick.label2)}
    return [
        t
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip() and id(t) not in hidden
    ]


def _hit(a, b) -> bool:
    return (
        min(a.x1, b.x1) - max(a.x0, b.x0) > TOLERANCE
        and min(a.y1, b.y1) - max(a.y0, b.y0) > TOLERANCE
    )


def text_overlaps(fig, renderer) -> list[str]:
    """Pairs of visible texts whose boxes intersect."""
    texts = _texts(fig)
    boxes = [t.get_window_extent(renderer) for t in texts]
    found = []
    for i in range(len(texts)):
        for j in range(i + 1, len(texts)):
            if _hit(boxes[i], boxes[j]):
                found.append(f"text {texts[i].get_text()!r} overlaps {texts[j].get_text()!r}")
    return found


def _data_points(ax) -> np.ndarray:
    """Display coordinates of the data an axes draws: line vertices, scatter offsets, band
    outlines, bar corners and centres."""
    pts = []
    for line in ax.get_lines():
        if isinstance(line, Line2D) and line.get_visible():
            xy = np.column_stack(line.get_data()).astype(float)
            pts.append(ax.transData.transform(xy[np.isfinite(xy).all(axis=1)]))
    for c in ax.collections:
        if not isinstance(c, Collection) or not c.get_visible():
            continue
        offsets = np.asarray(c.get_offsets(), float)
        if len(offsets) and c.get_offset_transform() is not None and len(c.get_paths()) <= 1:
            pts.append(c.get_offset_transform().transform(offsets))
        for path in c.get_paths()[:200]:
            v = np.asarray(path.vertices, float)
            if len(v):
                pts.append(c.get_transform().transform(v[np.isfinite(v).all(axis=1)]))
    for p in ax.patches:
        if isinstance(p, Rectangle) and p.get_visible() and p.get_height() and p.get_width():
            b = p.get_window_extent()
            pts.append(np.array([[b.x0, b.y1], [b.x1, b.y1], [(b.x0 + b.x1) / 2, b.y1]]))
    return np.concatenate(pts) if pts else np.empty((0, 2))


def legend_over_data(fig, renderer) -> list[str]:
    """Legends placed inside an axes that cover a point of its data."""
    found = []
    for ax in fig.axes:
        legend = ax.get_legend()
        if not isinstance(legend, Legend) or not legend.get_visible():
            continue
        box = legend.get_window_extent(renderer)
        pts = _data_points(ax)
        inside = (
            (pts[:, 0] > box.x0)
            & (pts[:, 0] < box.x1)
            & (pts[:, 1] > box.y0)
            & (pts[:, 1] < box.y1)
        )
        if inside.any():
            title = ax.get_title() or "an axes"
            found.append(f"the legend of {title!r} covers {int(inside.sum())} data points")
    return found


def problems(fig) -> list[str]:
    """Everything :mod:`this module <pipeline.report.overlap>` finds wrong with ``fig``."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return text_overlaps(fig, renderer) + legend_over_data(fig, renderer)
