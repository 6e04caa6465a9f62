"""Figures of the studies beyond the paper: collisions against recognition accuracy
(:func:`accuracy_curves`), collisions over generated layouts (:func:`layout_boxes`,
:func:`feature_scatter`), the DSS gain against obstacle repetition (:func:`gain_curves`) and the
camera robot against the grid (:func:`difference_figure`). Colours and the overlap check as in
:mod:`pipeline.report.figures`.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
from matplotlib import pyplot as plt
from matplotlib.ticker import MaxNLocator

from pipeline import palette
from pipeline.report.figures import BELOW, HUNG_BELOW, figure_legend, save
from pipeline.report.names import recogniser_colour
from pipeline.rl.rules import Rule
from pipeline.stats import bootstrap_difference


def accuracy_curves(
    panels: list[dict],
    path: Path,
    marker: float | None = None,
    marker_label: str = "",
    marker_colour: str = palette.series(0),
):
    """One panel per maze: collisions per run against the recognition accuracy ``p``. Each panel:
    ``title``; ``curves`` (label -> ``(p, mean, ci_low, ci_high)`` arrays: a line with its band);
    ``references`` (label -> ``(mean, ci_low, ci_high)``: a horizontal line with its band);
    ``colours`` (label -> colour: the methods' declared colours; curves without one take the
    cycle's by position). ``marker``: a dotted vertical line at that accuracy, named
    ``marker_label``, in ``marker_colour`` (the recogniser's declared colour)."""
    fig, axes = plt.subplots(1, len(panels), figsize=(4.3 * len(panels), 3.8), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        given = panel.get("colours", {})
        for i, (label, (x, mean, lo, hi)) in enumerate(panel["curves"].items()):
            colour = given.get(label) or palette.series(i)
            ax.plot(x, mean, "o-", color=colour, label=label, ms=3, lw=1.2)
            ax.fill_between(x, lo, hi, color=colour, alpha=0.2, lw=0)
        for j, (label, (mean, lo, hi)) in enumerate(panel["references"].items()):
            colour = given.get(label, "black")  # the method's colour, as everywhere
            ax.axhline(mean, color=colour, ls=("--", "-.", ":")[j % 3], lw=1.2, label=label)
            ax.axhspan(lo, hi, color=colour, alpha=0.1, lw=0)
        if marker is not None:
            ax.axvline(marker, color=marker_colour, ls=":", lw=1.4, label=marker_label)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("recognition accuracy p")
        ax.set_title(panel["title"], fontsize=10)
    axes[0][0].set_ylabel("collisions per run (mean, 95% CI)")
    legend = {}
    for ax in axes[0]:  # one legend below the panels, each label once
        for handle, label in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(label, handle)
    figure_legend(fig, legend.values(), legend.keys(), min(len(legend), 5), HUNG_BELOW)
    return save(fig, path)


def layout_boxes(
    per_size: dict[str, dict[str, np.ndarray]], path: Path, colours: dict[str, str] | None = None
):
    """One panel per size, one under the other: a box per method of its values over layouts
    (mean collisions per run of each layout), in the method's colour (``colours``: by label), log
    scale (zeros drawn at the axis' floor)."""
    n = max((len(b) for b in per_size.values()), default=1)
    fig, axes = plt.subplots(
        len(per_size),
        1,
        figsize=(1.15 * n + 1.5, 3.3 * len(per_size)),
        squeeze=False,
        layout="constrained",
    )
    for ax, (size, boxes) in zip(axes[:, 0], per_size.items()):
        labels = list(boxes)
        values = [np.asarray(boxes[k], dtype=float) for k in labels]
        floor = min([v[v > 0].min() for v in values if (v > 0).any()] or [1.0]) / 2
        drawn = ax.boxplot(
            [np.maximum(v, floor) for v in values],
            widths=0.6,
            flierprops={"markersize": 3},
            medianprops={"color": "black"},
            patch_artist=True,
        )
        for k, (box, label) in enumerate(zip(drawn["boxes"], labels)):
            colour = (colours or {}).get(label) or palette.series(k)
            box.set(facecolor=colour, alpha=0.35, edgecolor=colour)
        ax.set_yscale("log")
        ax.set_xticks(range(1, len(labels) + 1), [textwrap.fill(k, 13) for k in labels], fontsize=7)
        ax.set_title(f"{size}: {max((v.size for v in values), default=0)} layouts", fontsize=9)
        ax.set_ylabel("mean collisions per run (log)", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("Collisions over generated layouts", fontsize=10)
    return save(fig, path)


def feature_scatter(df, features: dict[str, str], path: Path, fit, colours: dict[str, str]):
    """Rows: sizes, columns: layout features; points: mean collisions per run of each (layout,
    method), one colour per method (``colours``: by ``df["method"]``, the declared colours; a
    method without one takes the palette's series colours), with ``fit(x, y)``'s line (slope,
    intercept, ...) where it gives one; log y. A feature that takes one value within every size
    has nothing to show and is left out; integer features get integer ticks; one legend, below."""
    sizes = list(dict.fromkeys(df["size"]))
    varied = {
        f: x
        for f, x in features.items()
        if any(df[df["size"] == s][f].nunique() > 1 for s in sizes)
    }
    fig, axes = plt.subplots(
        len(sizes),
        len(varied),
        figsize=(4.2 * len(varied), 3.2 * len(sizes) + 0.6),
        squeeze=False,
        layout="constrained",
    )
    for i, size in enumerate(sizes):
        on = df[df["size"] == size]
        for j, (feature, xlabel) in enumerate(varied.items()):
            ax = axes[i][j]
            for k, method in enumerate(dict.fromkeys(on["method"])):
                colour = colours.get(method) or palette.series(k)
                m = on[on["method"] == method]
                x, y = m[feature].to_numpy(float), m["collisions_mean"].to_numpy(float)
                ax.scatter(
                    x, np.maximum(y, 0.05), s=6, alpha=0.5, color=colour, label=m["label"].iloc[0]
                )
                line = fit(x, y)
                if line is not None:
                    xs = np.linspace(x.min(), x.max(), 20)
                    ax.plot(xs, np.maximum(line[1] + line[0] * xs, 0.05), color=colour, lw=1.2)
            ax.set_yscale("log")
            if np.allclose(on[feature], np.round(on[feature])):
                ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_title(size, fontsize=9)
            if j == 0:
                ax.set_ylabel("mean collisions per run (log)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    figure_legend(fig, handles, labels, 4, BELOW, markerscale=3)
    return save(fig, path)


def gain_curves(curves: dict[str, dict], beside: dict[str, dict], path: Path):
    """Two panels, the DSS gain and the relative gain against r: per recogniser (``curves``: label
    -> ``r`` and ``gain``/``relative`` as ``(mean, ci_low, ci_high)`` arrays) a line with its band,
    in the recogniser's declared colour (the series colours by position for one without); ``beside`` (label -> maze -> ``(r, gain, relative)``): points
    named by maze (Table 3's), in black, filled for the first label and hollow for the second."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.0))
    for ax, key, unit in (
        (axes[0], "gain", "DSS gain (collisions per run)"),
        (axes[1], "relative", "relative DSS gain"),
    ):
        for i, (label, c) in enumerate(curves.items()):
            mean, lo, hi = c[key]
            colour = recogniser_colour(label) or palette.series(i + 1)
            ax.plot(c["r"], mean, "o-", color=colour, label=label, ms=4, lw=1.4)
            ax.fill_between(c["r"], lo, hi, color=colour, alpha=0.2, lw=0)
        for j, (label, points) in enumerate(beside.items()):
            xs = [p[0] for p in points.values()]
            ys = [p[1 if key == "gain" else 2] for p in points.values()]
            ax.plot(
                xs,
                ys,
                ls=":",
                marker="s",
                color=palette.PAPER,
                mfc=palette.PAPER if j == 0 else "white",
                lw=0.8,
                ms=6,
                label=label,
            )
        ax.set_xlabel("r: cells per physical obstacle")
        ax.set_ylabel(unit)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylim(bottom=min(0, ax.get_ylim()[0]))
        ax.grid(alpha=0.3)
    axes[1].yaxis.set_major_formatter(lambda v, _: f"{100 * v:.0f}%")
    handles, labels = axes[0].get_legend_handles_labels()
    figure_legend(fig, handles, labels, min(len(labels), 3), HUNG_BELOW)
    fig.suptitle(
        "The DSS gain against obstacle repetition (11x11) and Table 3's mazes", fontsize=10
    )
    return save(fig, path)


#: The rules in the order of their colours and markers (palette.SERIES by position), the same in
#: every report: the decision rules as declared, then the methods that see no pictures.
RULES = (*(r.name for r in Rule), "no pictures")
MARKERS = ("o", "s", "D", "^")


def difference_figure(rows: list[tuple[str, str, np.ndarray, np.ndarray]], path: Path) -> Path:
    """``rows``: (cell label, rule name of :data:`RULES`, robot's collisions per run, grid's, paired
    by run), in the tables' order. Draws each row's paired difference with its interval, top to
    bottom, in the legend the rules that occur."""
    fig, ax = plt.subplots(figsize=(7.6, 1.2 + 0.32 * len(rows)), layout="constrained")
    for y, (_, rule, robot, grid) in enumerate(rows):
        estimate, lo, hi = bootstrap_difference(robot, grid, paired=True)
        k = RULES.index(rule)
        ax.errorbar(
            [estimate],
            [y],
            xerr=[[estimate - lo], [hi - estimate]],
            fmt=MARKERS[k % len(MARKERS)],
            color=palette.series(k),
            capsize=3,
            ms=6,
            label=rule,
        )
    ax.axvline(0, color=palette.GRID, lw=1, zorder=0)
    ax.set_yticks(range(len(rows)), [label for label, _, _, _ in rows], fontsize=8)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlabel("collisions per run, robot minus grid (paired by run; 95% bootstrap CI)")
    ax.set_title("The camera robot against the grid, by decision rule", fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    figure_legend(fig, unique.values(), unique.keys(), len(unique), title="decision rule")
    return save(fig, path)
