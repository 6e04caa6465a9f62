"""Figures of the report (bars, learning curves with bands, consecutive experiments, the learned path).

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

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Ellipse, Patch, Rectangle  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from pipeline import palette  # noqa: E402
from pipeline.report.overlap import FigureOverlapWarning, problems  # noqa: E402
from pipeline.report.stats import describe, mean_band  # noqa: E402
from pipeline.world.maze import MOVES  # noqa: E402
from pipeline.world.pictures import CATEGORIES  # noqa: E402

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


def style(styles: dict | None, label: str, i: int) -> dict:
    """The colour, line style and marker of ``label`` (``styles``: by label), else the i-th series
    colour, solid, no marker."""
    given = (styles or {}).get(label) or {}
    return {
        "color": given.get("color") or palette.SERIES[i % len(palette.SERIES)],
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


def bars(labels, samples, title, ylabel, path: Path, paper=None, styles=None):
    """Mean (bar, its value under the name) with s.d. (thin) and 95% bootstrap interval (thick)
    per label, the runs as dots, in each row's colour; the paper's numbers where given
    (:func:`paper_marks`), named in a legend above the axes."""
    fig, ax = plt.subplots(figsize=(max(5.0, 1.45 * len(labels) + 1.2), 4.2), layout="constrained")
    rng = np.random.default_rng(0)
    means = []
    for i, (label, v) in enumerate(zip(labels, samples)):
        d, colour = describe(v), style(styles, label, i)["color"]
        means.append(d["mean"])
        ax.bar(i, d["mean"], color=colour, alpha=0.3, edgecolor=colour, lw=1.2)
        ax.errorbar(i, d["mean"], yerr=d["std"], color="#555", capsize=4, lw=1)
        ax.vlines(i, d["ci_low"], d["ci_high"], color="black", lw=3, zorder=5)
        ax.scatter(i + rng.uniform(-0.3, 0.3, len(v)), v, s=4, color=colour, alpha=0.5, zorder=3)
    drawn = paper_marks(ax, paper)
    ticks(ax, labels, means)
    ax.set_xlim(-0.6, len(labels) - 0.4 + (0.35 if drawn else 0))
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    if drawn:
        fig.legend(
            drawn.values(),
            drawn.keys(),
            fontsize=7,
            loc="outside upper right",
            ncols=2,
            frameon=False,
        )
    return save(fig, path)


def curves(
    series: dict[str, np.ndarray],
    title: str,
    path: Path,
    ylabel="collisions per episode",
    xlabel: str = "episode",
    styles: dict[str, dict] | None = None,
    first: int = 0,
):
    """One line per label from x = ``first``: the mean over runs (rows of a runs x episodes array;
    a 1-D array is one run) with its 95% interval shaded (:func:`~pipeline.report.stats.mean_band`),
    drawn within the range of the values (collisions do not go below 0). Long runs get a
    logarithmic x axis beyond 10, collisions a logarithmic axis above 1 where early episodes
    collide many times; returns a note saying so for the caption ("" if linear). ``styles``: colour
    and dash by label (:func:`pipeline.report.names.row_styles`); the legend is below the axes."""
    fig, ax = plt.subplots(
        figsize=(6.4, 3.6 + 0.22 * ((len(series) + 1) // 2)), layout="constrained"
    )
    for i, (label, values) in enumerate(series.items()):
        mean, lo, hi = mean_band(values)
        x = np.arange(mean.size) + first
        s = style(styles, label, i)
        marks = np.unique(np.geomspace(1, max(mean.size, 1), 14).astype(int)) - 1
        ax.plot(
            x,
            mean,
            label=label,
            lw=1.4,
            color=s["color"],
            ls=s["ls"],
            marker=s["marker"],
            markevery=[int(m) for m in marks + i % 2 if m < mean.size],
            ms=5,
            fillstyle="none",
            mew=1.1,
        )
        v = np.atleast_2d(np.asarray(values, dtype=float))
        if v.shape[0] > 1 and np.isfinite(v).any():
            lo, hi = np.clip(lo, np.nanmin(v), None), np.clip(hi, None, np.nanmax(v))
            ax.fill_between(x, lo, hi, color=s["color"], alpha=0.15, lw=0)
    ax.set_xlim(left=first)
    values = [np.asarray(v, dtype=float) for v in series.values()]
    notes = []
    if (
        values
        and all(np.nanmin(v, initial=0) >= 0 for v in values)
        and max(np.nanmax(v, initial=0) for v in values) > 4
    ):
        # early episodes collide many times, later ones rarely: linear below 1, logarithmic above
        ax.set_yscale("symlog", linthresh=1.0, linscale=1.5)
        ax.set_ylim(bottom=0)
        ax.yaxis.set_major_formatter(PLAIN)
        notes.append(f"{ylabel} linear up to 1, logarithmic above")
    if max((np.atleast_2d(v).shape[1] for v in values), default=0) > 100:
        # the first episodes, where the methods differ most, get room: linear to 10, logarithmic on
        ax.set_xscale("symlog", linthresh=10.0, linscale=1.0)
        ax.set_xlim(left=first)
        ax.xaxis.set_major_formatter(PLAIN)
        notes.append(f"{xlabel} linear up to 10, logarithmic above")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    fig.legend(fontsize=8, loc="outside lower center", ncols=2, frameon=False)
    save(fig, path)
    return "; ".join(notes)


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
    fig.legend(
        [*handles, *drawn.values()],
        [*names, *drawn.keys()],
        fontsize=8,
        loc="outside lower center",
        ncols=3,
        frameon=False,
    )
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
