"""Learning curves: one line per row, the mean over runs with its 95% band, at a scale where the
rows of interest can be read.

Collisions per episode span two scales: the first episodes collide many times (up to 10 and more
in the large mazes), the later ones rarely (few-shot reasoning: a few hundredths). One y axis
cannot show both, and a symmetric-log axis squashes everything below 1 into a sliver. So a
learning curve whose early values dwarf its later ones gets two panels side by side: the first
:data:`EARLY` episodes at their full scale, and the rest at the scale of the later episodes. A
row that stays far above the others there (Q-learning, which keeps colliding) leaves the right
panel's top and the caption says up to what value. On the right each point is a run's mean over
its last :data:`WINDOW` episodes: a collision every few hundred episodes reads as a rate there, not
as spikes.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from pipeline.report.figures import PLAIN, figure_legend, save, style
from pipeline.stats import mean_band

#: The episodes the left panel shows at the full scale (from the first one drawn).
EARLY = 10
#: A row leaves the right panel when its later mean exceeds this multiple of the next row's.
DWARFS = 10.0
#: The right panel's window: each point is a run's mean over its last WINDOW episodes.
WINDOW = 20
#: Headroom above the highest band drawn in full on the right panel.
HEADROOM = 1.15


def curves(
    series: dict[str, np.ndarray],
    title: str,
    path: Path,
    ylabel="collisions per episode",
    xlabel: str = "episode",
    styles: dict[str, dict] | None = None,
    first: int = 0,
) -> str:
    """One line per label from x = ``first``: the mean over runs (rows of a runs x episodes array;
    a 1-D array is one run) with its 95% t interval shaded (:func:`~pipeline.stats.mean_band`),
    clipped to the range of the values. ``styles``: colour, dash and marker by label
    (:func:`pipeline.report.names.row_styles`); the legend is below the axes. Returns what the
    caption must say about the scales ("" for one linear panel)."""
    bands = {label: band(values) for label, values in series.items()}
    length = max((b[0].size for b in bands.values()), default=0)
    two_scales = length > 4 * EARLY and early_dwarfs_late(bands)
    fig, axes = plt.subplots(
        1,
        2 if two_scales else 1,
        figsize=(9.6 if two_scales else 6.4, 3.6 + 0.22 * ((len(series) + 1) // 2)),
        gridspec_kw={"width_ratios": [1, 2.2]} if two_scales else None,
        squeeze=False,
        layout="constrained",
    )
    for i, (label, b) in enumerate(bands.items()):
        draw(axes[0][0], np.arange(b[0].size) + first, b, label, style(styles, label, i), i)
    notes = []
    if two_scales:
        later = {
            label: band(window_means(np.atleast_2d(values)[:, EARLY:]))
            for label, values in series.items()
        }
        for i, (label, b) in enumerate(later.items()):
            x = np.arange(b[0].size) + first + EARLY
            draw(axes[0][1], x, b, label, style(styles, label, i), i)
        notes.append(split_scales(axes[0][0], axes[0][1], later, first, length, xlabel, ylabel))
    else:
        ax = axes[0][0]
        ax.set_xlim(left=first)
        if length > 100:  # the first episodes, where the methods differ most, get room
            ax.set_xscale("symlog", linthresh=10.0, linscale=1.0)
            ax.set_xlim(left=first)
            ax.xaxis.set_major_formatter(PLAIN)
            notes.append(f"{xlabel} linear up to 10, logarithmic above")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)
    if two_scales:
        fig.suptitle(title, fontsize=10)
    handles, labels = axes[0][0].get_legend_handles_labels()
    figure_legend(fig, handles, labels, 2)
    save(fig, path)
    return "; ".join(notes)


def band(values) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean over runs and its 95% band, the band clipped to the range of the values (a count
    does not go below 0)."""
    mean, lo, hi = mean_band(values)
    v = np.atleast_2d(np.asarray(values, dtype=float))
    if v.shape[0] > 1 and np.isfinite(v).any():
        lo, hi = np.clip(lo, np.nanmin(v), None), np.clip(hi, None, np.nanmax(v))
    return mean, lo, hi


def window_means(values) -> np.ndarray:
    """Each run's mean over the last :data:`WINDOW` episodes up to each episode (fewer at the
    start): a rare event (a few hundredths a run) reads as a rate, not as spikes."""
    v = np.atleast_2d(np.asarray(values, dtype=float))
    sums = np.cumsum(np.nan_to_num(v), axis=1)
    counts = np.cumsum(~np.isnan(v), axis=1)
    back = np.pad(sums, ((0, 0), (WINDOW, 0)))[:, : v.shape[1]]
    back_counts = np.pad(counts, ((0, 0), (WINDOW, 0)))[:, : v.shape[1]]
    with np.errstate(invalid="ignore", divide="ignore"):
        return (sums - back) / (counts - back_counts)


def early_dwarfs_late(bands: dict) -> bool:
    """Whether the first :data:`EARLY` episodes reach above 4 while the rest stay below a quarter
    of that: two scales, one figure."""
    early = max((np.nanmax(m[:EARLY], initial=0) for m, _, _ in bands.values()), default=0)
    late = max((np.nanmax(m[EARLY:], initial=0) for m, _, _ in bands.values()), default=0)
    return early > 4 and late < early / 4


def draw(ax, x, row_band: tuple, label: str, s: dict, i: int) -> None:
    """A row's mean as a line (its marker every few points, spread out on a log axis) and its band
    (``row_band``: :func:`band`)."""
    mean, lo, hi = row_band
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
    if np.any(hi > lo):
        ax.fill_between(x, lo, hi, color=s["color"], alpha=0.15, lw=0)


def split_scales(early, late, later: dict, first: int, length: int, xlabel, ylabel) -> str:
    """The left panel: episodes ``first`` to ``first + EARLY``, full scale; the right one: the rest
    (``later``: label -> its band from there on), logarithmic in x, its y top at the highest band of
    the rows that do not dwarf the others. Returns the caption's words for the two panels and for a
    row above the right panel's top."""
    end = first + length - 1
    early.set_xlim(first, first + EARLY)
    early.set_ylim(bottom=0)
    early.set_title(f"{xlabel}s {first}-{first + EARLY}", fontsize=9)
    early.set_xlabel(xlabel)
    early.set_ylabel(ylabel)
    peaks = sorted(
        ((np.nanmax(m, initial=0), label) for label, (m, _, _) in later.items()), reverse=True
    )
    above = []
    for k, (peak, _) in enumerate(peaks[:-1]):  # the first gap from the top
        if peak > DWARFS * max(peaks[k + 1][0], 1e-9):
            above = peaks[: k + 1]
            break
    kept = [later[label][2] for label in later if label not in {name for _, name in above}]
    top = HEADROOM * max((np.nanmax(h, initial=0) for h in kept), default=1.0) or 1.0
    late.set_xscale("log")
    late.set_xlim(first + EARLY, end)
    late.set_ylim(0, top)
    late.xaxis.set_major_formatter(PLAIN)
    late.set_title(
        f"{xlabel}s {first + EARLY}-{end} (logarithmic), mean of the last {WINDOW}", fontsize=9
    )
    late.set_xlabel(xlabel)
    words = (
        f"left: {xlabel}s {first}-{first + EARLY} at full scale; right: {xlabel}s "
        f"{first + EARLY}-{end} ({xlabel} logarithmic) at the scale of the later {xlabel}s, each "
        f"point a run's mean over its last {WINDOW} {xlabel}s"
    )
    if above:
        rows = ", ".join(f"{name} (up to {peak:.2f})" for peak, name in sorted(above))
        words += f", where {rows} {'runs' if len(above) == 1 else 'run'} above the top"
    return words
