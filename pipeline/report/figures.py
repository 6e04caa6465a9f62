"""Figures of the report (bars, learning curves with bands, consecutive experiments, the learned path).

Every figure is drawn from recorded data by a pure function and saved without timestamps, so the
same records give the same PNG bytes.
"""

from __future__ import annotations

import textwrap
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from pipeline.report.stats import describe, mean_band  # noqa: E402
from pipeline.world.maze import MOVES  # noqa: E402
from pipeline.world.pictures import CATEGORIES  # noqa: E402

CATEGORY_COLOURS = ("#8c564b", "#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd")


def save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata={"Software": None}, bbox_inches="tight")
    plt.close(fig)
    return path


def ticks(ax, labels) -> None:
    """Labels as the ticks of a bar chart, wrapped; a name all labels begin with (``Few-shot +
    DSS, way 1``, ``..., way 2``) goes to the axis label instead."""
    labels = list(labels)
    heads = {label.split(", ", 1)[0] for label in labels}
    if len(heads) == 1 and len(labels) > 1 and all(", " in label for label in labels):
        ax.set_xlabel(heads.pop())
        labels = [label.split(", ", 1)[1] for label in labels]
    ax.set_xticks(range(len(labels)), [textwrap.fill(label, 16) for label in labels])


def paper_marks(ax, paper) -> None:
    """The paper's numbers (``paper``: per bar a :class:`~pipeline.report.paper_numbers.PaperValue` or
    None) as red dashes over the bars, dashed where the paper's number pools more cells, with
    the value beside; a legend names them."""
    drawn, last = {}, {}
    for i, ref in enumerate(paper or []):
        value = ref.number() if ref is not None else None
        if value is None:
            continue
        label = f"paper ({ref.source}{', ' + ref.pools if ref.pools else ''})"
        drawn[label] = ax.hlines(
            value,
            i - 0.42,
            i + 0.42,
            colors="red",
            linestyles="--" if ref.pools else "-",
            lw=2,
            zorder=4,
        )
        last[(label, value)] = i
    for (_, value), i in last.items():  # the value once, at the last bar it marks
        ax.text(i + 0.42, value, f"{value:g}", color="red", fontsize=7, ha="right", va="bottom")
    if drawn:
        ax.set_ylim(top=ax.get_ylim()[1] * 1.3)  # room for the legend above the marks
        ax.legend(drawn.values(), drawn.keys(), fontsize=7, loc="upper right")


def bars(labels, samples, title, ylabel, path: Path, paper=None):
    """Mean with s.d. (thin) and 95% bootstrap interval (thick) per label, the runs as dots; the
    paper's numbers where given (:func:`paper_marks`)."""
    fig, ax = plt.subplots(figsize=(1.3 * len(labels) + 2, 3.6))
    rng = np.random.default_rng(0)
    for i, (_label, v) in enumerate(zip(labels, samples)):
        d = describe(v)
        ax.bar(i, d["mean"], color="#9ecae1", edgecolor="#3182bd")
        ax.errorbar(i, d["mean"], yerr=d["std"], color="#555", capsize=4, lw=1)
        ax.vlines(i, d["ci_low"], d["ci_high"], color="black", lw=3)
        ax.scatter(
            i + rng.uniform(-0.25, 0.25, len(v)), v, s=4, color="#3182bd", alpha=0.4, zorder=3
        )
        ax.text(i, d["mean"], f"{d['mean']:.1f}", ha="center", va="bottom", fontsize=8)
    paper_marks(ax, paper)
    ticks(ax, labels)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    return save(fig, path)


def curves(
    series: dict[str, np.ndarray],
    title: str,
    path: Path,
    ylabel="collisions per episode",
    xlabel: str = "episode",
    colours: dict[str, str] | None = None,
):
    """One line per label from x = 0: the mean over runs (rows of a runs x episodes array; a 1-D
    array is one run) with its 95% interval shaded (:func:`~pipeline.report.stats.mean_band`),
    drawn within the range of the values (collisions do not go below 0). Long runs get a
    logarithmic episode axis beyond episode 10, collisions a logarithmic axis above 1 where early
    episodes collide many times; returns a note saying so for the caption ("" if linear).
    ``colours``: by label (the methods' declared colours); others take the next of the cycle."""
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for label, values in series.items():
        mean, lo, hi = mean_band(values)
        x = np.arange(mean.size)
        given = {"color": colours[label]} if colours and label in colours else {}
        (line,) = ax.plot(x, mean, label=label, lw=1.2, **given)
        v = np.atleast_2d(np.asarray(values, dtype=float))
        if v.shape[0] > 1 and np.isfinite(v).any():
            lo, hi = np.clip(lo, np.nanmin(v), None), np.clip(hi, None, np.nanmax(v))
            ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
    ax.set_xlim(left=0)
    values = [np.asarray(v, dtype=float) for v in series.values()]
    notes = []
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    if (
        values
        and all(np.nanmin(v, initial=0) >= 0 for v in values)
        and max(np.nanmax(v, initial=0) for v in values) > 4
    ):
        # early episodes collide many times, later ones rarely: linear below 1, logarithmic above
        ax.set_yscale("symlog", linthresh=1.0, linscale=1.5)
        ax.set_ylim(bottom=0)
        ax.yaxis.set_major_formatter(plain)
        notes.append(f"{ylabel} linear up to 1, logarithmic above")
    if max((np.atleast_2d(v).shape[1] for v in values), default=0) > 100:
        # the first episodes, where the methods differ most, get room: linear to 10, logarithmic on
        ax.set_xscale("symlog", linthresh=10.0, linscale=1.0)
        ax.set_xlim(left=0)
        ax.xaxis.set_major_formatter(plain)
        notes.append(f"{xlabel} linear up to 10, logarithmic above")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    save(fig, path)
    return "; ".join(notes)


def long_term(series: dict[str, np.ndarray], title: str, path: Path, paper=None):
    """Collisions of each consecutive experiment (the runs in order) per label, and their means
    with 95% bootstrap intervals and the paper's numbers where given (:func:`paper_marks`)."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), gridspec_kw={"width_ratios": [2.2, 1]})
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (label, values) in enumerate(series.items()):
        ax1.plot(
            np.arange(1, len(values) + 1),
            values,
            label=label,
            lw=1.2,
            color=colours[i % len(colours)],
        )
        d = describe(values)
        ax2.bar(i, d["mean"], color=colours[i % len(colours)], alpha=0.5)
        ax2.vlines(i, d["ci_low"], d["ci_high"], color="black", lw=3)
    paper_marks(ax2, paper)
    ax1.set_xlabel("experiment (consecutive runs)")
    ax1.set_ylabel("collisions per experiment")
    ax1.legend(fontsize=8)
    ticks(ax2, series)
    ax2.set_title("mean, 95% CI", fontsize=9)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def optimal_path(
    layout: list[str], obstacles: list[dict], path_cells: list[int], title: str, path: Path
):
    """Figure 7: the maze, obstacles coloured by category, and the learned path."""
    h, w = len(layout), len(layout[0])
    fig, ax = plt.subplots(figsize=(0.6 * w + 1.5, 0.6 * h + 0.8))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(-0.5, w, 1), [])
    ax.set_yticks(np.arange(-0.5, h, 1), [])
    ax.grid(color="#ccc")
    by_cell = {o["cell"]: o for o in obstacles}
    for r, row in enumerate(layout):
        for c, ch in enumerate(row):
            if ch == "X":
                o = by_cell.get(r * w + c)
                colour = CATEGORY_COLOURS[o["category"]] if o else "black"
                ax.add_patch(plt.Rectangle((c - 0.5, r - 0.5), 1, 1, color=colour))
            elif ch == "S":
                ax.add_patch(plt.Rectangle((c - 0.4, r - 0.4), 0.8, 0.8, color="red"))
            elif ch == "G":
                ax.add_patch(matplotlib.patches.Ellipse((c, r), 0.8, 0.5, color="gold"))
    if path_cells:
        rc = np.array([divmod(s, w) for s in path_cells])
        ax.plot(rc[:, 1], rc[:, 0], "o-", color="#1f77b4", ms=6)
    handles = [
        matplotlib.patches.Patch(color=c, label=n) for c, n in zip(CATEGORY_COLOURS, CATEGORIES)
    ]
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1))
    ax.set_title(title, fontsize=9)
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


def accuracy_curves(
    panels: list[dict], path: Path, marker: float | None = None, marker_label: str = ""
):
    """One panel per maze: collisions per run against the recognition accuracy ``p``. Each panel:
    ``title``; ``curves`` (label -> ``(p, mean, ci_low, ci_high)`` arrays: a line with its band);
    ``references`` (label -> ``(mean, ci_low, ci_high)``: a horizontal line with its band);
    ``measured`` (curve label -> ``(x, mean, ci_low, ci_high)``: a star with its interval, in the
    colour of that curve); ``colours`` (curve label -> colour: the methods' declared colours;
    others take the cycle's by position). ``marker``: a vertical line at that accuracy, named
    ``marker_label``."""
    fig, axes = plt.subplots(1, len(panels), figsize=(4.3 * len(panels), 3.8), squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, panel in zip(axes[0], panels):
        given = panel.get("colours", {})
        colour = {
            label: given.get(label) or colours[i % len(colours)]
            for i, label in enumerate(panel["curves"])
        }
        for label, (x, mean, lo, hi) in panel["curves"].items():
            ax.plot(x, mean, "o-", color=colour[label], label=label, ms=3, lw=1.2)
            ax.fill_between(x, lo, hi, color=colour[label], alpha=0.2, lw=0)
        for j, (label, (mean, lo, hi)) in enumerate(panel["references"].items()):
            ax.axhline(mean, color="black", ls=("--", "-.", ":")[j % 3], lw=1, label=label)
            ax.axhspan(lo, hi, color="black", alpha=0.08, lw=0)
        for label, (x, mean, lo, hi) in panel.get("measured", {}).items():
            ax.errorbar(
                [x],
                [mean],
                yerr=[[mean - lo], [hi - mean]],
                fmt="*",
                ms=11,
                capsize=3,
                color=colour.get(label, "red"),
                mec="black",
                mew=0.5,
                zorder=5,
                label=f"{label}, Relation Network",
            )
        if marker is not None:
            ax.axvline(marker, color="red", ls=":", lw=1, label=marker_label)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("recognition accuracy p")
        ax.set_title(panel["title"], fontsize=10)
    axes[0][0].set_ylabel("collisions per run (mean, 95% CI)")
    legend = {}
    for ax in axes[0]:  # one legend below the panels, each label once
        legend.update(
            {
                label: handle
                for handle, label in zip(*ax.get_legend_handles_labels())
                if label not in legend
            }
        )
    fig.legend(
        legend.values(),
        legend.keys(),
        fontsize=8,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        ncol=min(len(legend), 5),
        frameon=False,
    )
    return save(fig, path)


def layout_boxes(per_size: dict[str, dict[str, np.ndarray]], path: Path):
    """One panel per size: a box per method of its values over layouts (mean collisions per run of
    each layout), log scale (zeros drawn at the axis' floor)."""
    fig, axes = plt.subplots(
        1, len(per_size), figsize=(4.6 * len(per_size), 4.2), squeeze=False, layout="constrained"
    )
    for ax, (size, boxes) in zip(axes[0], per_size.items()):
        labels = list(boxes)
        values = [np.asarray(boxes[k], dtype=float) for k in labels]
        floor = min([v[v > 0].min() for v in values if (v > 0).any()] or [1.0]) / 2
        ax.boxplot([np.maximum(v, floor) for v in values], widths=0.6, flierprops={"markersize": 3})
        ax.set_yscale("log")
        ax.set_xticks(
            range(1, len(labels) + 1),
            [textwrap.fill(k, 12) for k in labels],
            fontsize=7,
            rotation=45,
            ha="right",
        )
        ax.set_title(f"{size}: {max((v.size for v in values), default=0)} layouts")
        ax.set_ylabel("mean collisions per run (log)")
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("Collisions over generated layouts")
    return save(fig, path)


def feature_scatter(df, features: dict[str, str], path: Path, fit, colours: dict[str, str]):
    """Rows: sizes, columns: layout features; points: mean collisions per run of each (layout,
    method), one colour per method (``colours``: by ``df["method"]``, the declared colours; a
    method without one takes tab10's by position), with ``fit(x, y)``'s line (slope, intercept,
    ...) where it gives one; log y."""
    sizes = list(dict.fromkeys(df["size"]))
    fig, axes = plt.subplots(
        len(sizes),
        len(features),
        figsize=(4.2 * len(features), 3.4 * len(sizes)),
        squeeze=False,
        layout="constrained",
    )
    cycle = plt.get_cmap("tab10")
    for i, size in enumerate(sizes):
        on = df[df["size"] == size]
        for j, (feature, xlabel) in enumerate(features.items()):
            ax = axes[i][j]
            for k, method in enumerate(dict.fromkeys(on["method"])):
                colour = colours.get(method) or cycle(k)
                m = on[on["method"] == method]
                x, y = m[feature].to_numpy(float), m["collisions_mean"].to_numpy(float)
                ax.scatter(
                    x,
                    np.maximum(y, 0.05),
                    s=6,
                    alpha=0.5,
                    color=colour,
                    label=m["label"].iloc[0],
                )
                line = fit(x, y)
                if line is not None:
                    xs = np.linspace(x.min(), x.max(), 20)
                    ax.plot(xs, np.maximum(line[1] + line[0] * xs, 0.05), color=colour, lw=1.2)
            ax.set_yscale("log")
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_title(size, fontsize=9)
            if j == 0:
                ax.set_ylabel("mean collisions per run (log)")
    axes[0][0].legend(fontsize=6, markerscale=2)
    return save(fig, path)
