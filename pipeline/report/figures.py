"""Figures of the report (bars, consecutive experiments, the learned path; the learning curves are
:mod:`pipeline.report.learning_curves`).

Every figure is drawn from recorded data by a pure function and saved without timestamps, so the
same records give the same PNG bytes. Colours come from the one palette (:mod:`pipeline.palette`)
and a row's style from :func:`pipeline.report.names.row_styles`; legends sit outside the axes,
and :func:`save` checks that no text overlaps another and no legend covers data
(:mod:`pipeline.report.overlap`).
"""

from __future__ import annotations

import textwrap
import warnings
from collections import Counter
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Ellipse, Patch, Rectangle
from matplotlib.ticker import FuncFormatter

from pipeline import palette
from pipeline.report.overlap import FigureOverlapWarning, problems
from pipeline.stats import describe
from pipeline.world.maze import MOVES
from pipeline.world.pictures import CATEGORIES

matplotlib.use("Agg")  # every module that draws saves through this one: files only, no window

PLAIN = FuncFormatter(lambda v, _: f"{v:g}")


def save(fig, path: Path) -> Path:
    """Write ``fig`` as a PNG; a figure with overlapping texts or a legend over its data warns
    first (:mod:`pipeline.report.overlap`; the tests make the warning an error)."""
    found = problems(fig)
    if found:
        warnings.warn(f"{path.name}: {'; '.join(found[:6])}", FigureOverlapWarning, stacklevel=2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata={"Software": None}, bbox_inches="tight")
    plt.close(fig)
    return path


#: Where :func:`figure_legend` puts a legend: below the axes of a constrained layout, or (a figure
#: without one) hung from the figure's bottom edge.
BELOW = {"loc": "outside lower center"}
HUNG_BELOW = {"loc": "upper center", "bbox_to_anchor": (0.5, 0.0)}


def figure_legend(fig, handles, labels, ncols: int, placement=BELOW, **options) -> None:
    """One frameless legend for the whole figure, below its axes unless ``placement`` says
    otherwise (``options``: ``fontsize``, 8 unless given, and any other of ``Figure.legend``'s)."""
    options.setdefault("fontsize", 8)
    fig.legend(handles, labels, **placement, ncols=ncols, frameon=False, **options)


def style(styles: dict | None, label: str, i: int) -> dict:
    """The colour, line style and marker of ``label`` (``styles``: by label), else the i-th series
    colour, solid, no marker."""
    given = (styles or {}).get(label) or {}
    return {
        "color": given.get("color") or palette.series(i),
        "ls": given.get("ls", "-"),
        "marker": given.get("marker"),
    }


def ticks(ax, labels, means=None) -> None:
    """Labels as the ticks of a bar chart, wrapped, each with its mean below; a name all labels
    begin with (``Few-shot + DSS, way 1``, ``..., way 2``) goes to the axis label instead."""
    labels = list(labels)
    heads = {label.split(", ", 1)[0] for label in labels}
    if len(heads) == 1 and len(labels) > 1 and all(", " in label for label in labels):
        ax.set_xlabel(heads.pop())
        labels = [label.split(", ", 1)[1] for label in labels]
    shown = [textwrap.fill(label, 15) for label in labels]
    if means is not None:
        shown = [f"{t}\nmean {m:.1f}" for t, m in zip(shown, means)]
    ax.set_xticks(range(len(labels)), shown, fontsize=8)


def paper_marks(ax, paper) -> dict:
    """The paper's numbers (``paper``: per bar a :class:`~pipeline.report.paper_numbers.PaperValue`
    or None) as dashes across the bars in the paper's colour, dashed where the paper's number
    pools more cells, with the value at the dash's right end; returns the legend entries."""
    drawn, last = {}, {}
    for i, ref in enumerate(paper or []):
        value = ref.number() if ref is not None else None
        if value is None:
            continue
        label = f"paper ({ref.source}{', ' + ref.pools if ref.pools else ''})"
        dash = "--" if ref.pools else "-"
        drawn[label] = ax.hlines(
            value, i - 0.42, i + 0.42, colors=palette.PAPER, linestyles=dash, lw=2, zorder=4
        )
        last[(label, value)] = i
    for (_, value), i in last.items():  # the value once, right of the last bar it marks
        ax.annotate(
            f"{value:g}",
            (i + 0.42, value),
            xytext=(2, 0),
            textcoords="offset points",
            color=palette.PAPER,
            fontsize=7,
            ha="left",
            va="center",
        )
    return drawn


#: A bar chart breaks its y axis when its highest bars' means exceed this multiple of the rest's
#: highest (Figure 8: Q-learning's 173.5 against the others' 5-13).
DWARFING = 4.0


def bars(labels, samples, title, ylabel, path: Path, paper=None, styles=None) -> str:
    """Mean (bar, its value under the name) with s.d. (thin) and 95% bootstrap interval (thick)
    per label, the runs as dots, in each row's colour; the paper's numbers where given
    (:func:`paper_marks`), named in a legend above the axes. When some bars dwarf the others
    (:data:`DWARFING`) the y axis is broken: the others keep a readable scale below the break.
    Returns what the caption must say about the axis ("" when it is whole)."""
    described = [describe(v) for v in samples]
    means = [d["mean"] for d in described]
    high = dwarfing(means)
    fig, axes = plt.subplots(
        2 if high else 1,
        1,
        sharex=True,
        squeeze=False,
        figsize=(max(5.0, 1.45 * len(labels) + 1.2), 4.8 if high else 4.2),
        gridspec_kw={"height_ratios": [1, 2.6], "hspace": 0.05} if high else None,
        layout="constrained",
    )
    for ax in axes[:, 0]:
        rng = np.random.default_rng(0)  # the same jitter in both halves of a broken axis
        for i, (label, v, d) in enumerate(zip(labels, samples, described)):
            colour = style(styles, label, i)["color"]
            ax.bar(i, d["mean"], color=colour, alpha=0.3, edgecolor=colour, lw=1.2)
            ax.errorbar(i, d["mean"], yerr=d["std"], color="#555", capsize=4, lw=1)
            ax.vlines(i, d["ci_low"], d["ci_high"], color="black", lw=3, zorder=5)
            ax.scatter(
                i + rng.uniform(-0.3, 0.3, len(v)), v, s=4, color=colour, alpha=0.5, zorder=3
            )
        drawn = paper_marks(ax, paper)
    bottom = axes[-1, 0]
    ticks(bottom, labels, means)
    bottom.set_xlim(-0.6, len(labels) - 0.4 + (0.35 if drawn else 0))
    bottom.set_ylabel(ylabel)
    axes[0, 0].set_title(title, fontsize=10)
    note = break_axis(axes[0, 0], bottom, samples, high, paper) if high else ""
    if drawn:  # the paper's marks, named above the axes
        figure_legend(
            fig, drawn.values(), drawn.keys(), 2, {"loc": "outside upper right"}, fontsize=7
        )
    save(fig, path)
    return note


def dwarfing(means: list[float]) -> list[int]:
    """The bars (indices) whose means exceed :data:`DWARFING` times every other bar's: those above
    the first such gap from the top; none when there is no such gap."""
    order = sorted(range(len(means)), key=lambda i: -means[i])
    for k in range(len(order) - 1):
        if means[order[k]] > DWARFING * max(means[order[k + 1]], 1e-9):
            return order[: k + 1]
    return []


def break_axis(top, bottom, samples, high: list[int], paper) -> str:
    """Split the y axis between the highest runs of the bars below the break (with the paper's
    numbers) and the lowest runs of the bars above it; diagonal marks where it breaks. Returns
    the caption's words."""
    below = [np.max(v) for i, v in enumerate(samples) if i not in high]
    below += [ref.number() for ref in paper or [] if ref is not None and ref.number() is not None]
    above = [v for i, v in enumerate(samples) if i in high]
    lower_top = 1.15 * max(below)
    upper = (0.95 * min(np.min(v) for v in above), 1.05 * max(np.max(v) for v in above))
    bottom.set_ylim(0, lower_top)
    top.set_ylim(*upper)
    top.spines.bottom.set_visible(False)
    bottom.spines.top.set_visible(False)
    top.tick_params(bottom=False)
    marks = {"marker": [(-1, -0.5), (1, 0.5)], "ms": 10, "ls": "none", "color": "k", "mec": "k"}
    top.plot([0, 1], [0, 0], transform=top.transAxes, clip_on=False, **marks)
    bottom.plot([0, 1], [1, 1], transform=bottom.transAxes, clip_on=False, **marks)
    return f"the y axis is broken between {lower_top:.3g} and {upper[0]:.3g}"


def long_term(series: dict[str, np.ndarray], title: str, path: Path, paper=None, styles=None):
    """Collisions of each consecutive experiment (numbered from 1, the runs in order) per label,
    and their means with 95% bootstrap intervals and the paper's numbers where given
    (:func:`paper_marks`). The bars' panel widens with their number (1.55 inches a bar from 2)."""
    bars = max(len(series), 2)
    fig, (ax1, ax2) = plt.subplots(
        1,
        2,
        figsize=(6.9 + 1.55 * bars, 4.2),
        gridspec_kw={"width_ratios": [2.2, 0.5 * bars]},
        layout="constrained",
    )
    for i, (label, values) in enumerate(series.items()):
        s = style(styles, label, i)
        ax1.plot(
            np.arange(1, len(values) + 1), values, label=label, lw=1.2, color=s["color"], ls=s["ls"]
        )
        d = describe(values)
        ax2.bar(i, d["mean"], color=s["color"], alpha=0.3, edgecolor=s["color"])
        ax2.vlines(i, d["ci_low"], d["ci_high"], color="black", lw=3)
    drawn = paper_marks(ax2, paper)
    ax1.set_xlim(1, max((len(v) for v in series.values()), default=1))
    ax1.set_xlabel("experiment (consecutive runs, from 1)")
    ax1.set_ylabel("collisions per experiment")
    ticks(ax2, series)
    ax2.set_xlim(-0.6, len(series) - 0.4 + (0.5 if drawn else 0))
    ax2.set_title("mean, 95% CI", fontsize=9)
    handles, names = ax1.get_legend_handles_labels()
    figure_legend(fig, [*handles, *drawn.values()], [*names, *drawn.keys()], 3)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def optimal_path(
    layout: list[str], obstacles: list[dict], path_cells: list[int], title: str, path: Path
):
    """Figure 7: the maze, obstacles in their category colours, start and goal, the learned path
    (the palette's colours; a legend right of the maze names each)."""
    h, w = len(layout), len(layout[0])
    fig, ax = plt.subplots(figsize=(0.6 * w + 2.2, 0.6 * h + 0.8))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(-0.5, w, 1), [])
    ax.set_yticks(np.arange(-0.5, h, 1), [])
    ax.tick_params(length=0)
    ax.grid(color=palette.GRID)
    by_cell = {o["cell"]: o for o in obstacles}
    for r, row in enumerate(layout):
        for c, ch in enumerate(row):
            if ch == "X":
                o = by_cell.get(r * w + c)
                colour = palette.category(o["category"]) if o else palette.OTHER_CATEGORY
                ax.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, color=colour))
            elif ch == "S":
                ax.add_patch(Rectangle((c - 0.4, r - 0.4), 0.8, 0.8, color=palette.START))
            elif ch == "G":
                ax.add_patch(Ellipse((c, r), 0.8, 0.5, color=palette.GOAL))
    if path_cells:
        rc = np.array([divmod(s, w) for s in path_cells])
        ax.plot(rc[:, 1], rc[:, 0], "o-", color=palette.ROBOT, ms=5, lw=1.5)
    handles = [Patch(color=palette.category(k), label=n) for k, n in enumerate(CATEGORIES)]
    handles += [Patch(color=palette.START, label="start"), Patch(color=palette.GOAL, label="goal")]
    handles += [plt.Line2D([], [], color=palette.ROBOT, marker="o", ms=5, label="learned path")]
    ax.legend(
        handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1), frameon=False
    )
    ax.set_title(textwrap.fill(title, 48), fontsize=9)
    return save(fig, path)


def modal_final_path(steps_df, width: int, goal: int) -> list[int]:
    """The most common path of the runs' last episodes that reached the goal in the fewest steps."""
    last = steps_df[steps_df["episode"] == steps_df.groupby("run")["episode"].transform("max")]
    paths = []
    for _, g in last.sort_values(["run", "step"]).groupby("run"):
        states = g["state"].tolist()
        actions = g["action"].tolist()
        if not states:
            continue
        r, c = divmod(states[-1], width)
        dr, dc = MOVES[actions[-1]]
        if (r + dr) * width + (c + dc) == goal:
            paths.append(tuple(states) + (goal,))
    if not paths:
        return []
    shortest = min(len(p) for p in paths)
    return list(Counter(p for p in paths if len(p) == shortest).most_common(1)[0][0])
