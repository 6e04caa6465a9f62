"""The robot section's figure: where the camera robot collides more than the grid, and by how much.

One row per robot cell (method, maze, recogniser), one colour per decision rule: the paired
difference in collisions per run, robot minus its grid twin (the same run seeds, so the same
obstacles), with its 95% paired bootstrap interval. A row at 0 with no interval is a method whose
robot and grid collide identically run for run (the ones that see no pictures). The tables beside
it hold the numbers (:mod:`pipeline.report.robot`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from pipeline import palette
from pipeline.report.figures import figure_legend, save
from pipeline.rl.rules import Rule
from pipeline.stats import bootstrap_difference

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
