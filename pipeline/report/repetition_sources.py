"""The repetition section's split of the DSS gain by where the substituted picture comes from
(issue 42; ``learn_from`` in ``pipeline/fewshot/learn_from.py``).

The repetition experiment runs few-shot reasoning with the DSS also under ``learn_from`` =
``same_picture``, ``same_object`` and ``same_category``: the same collisions and substitutions,
but a query picture sees only the substituted pictures of its own group. The reach grows from
the picture itself to every picture, so on every layout and run seed the collisions per run fall
in steps whose sum is the whole DSS gain (without the DSS minus with it):

- **same face**: without the DSS − ``same_picture`` (the picture itself, seen again);
- **other faces of the obstacle**: ``same_picture`` − ``same_object``;
- **the category's other obstacle**: ``same_object`` − ``same_category`` (a different object:
  the category's two obstacles are two distinct objects, ``obstacle_models.obstacle_instance``);
- **other categories**: ``same_category`` − the full DSS (a substitution into another category
  moves that category's scores for every picture).

Each step is a paired difference (same layout, same run seeds); its mean over layouts has a 95%
bootstrap interval over layouts, as the section's other tables.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pandas as pd

from pipeline.report.experiments import Cell, Experiment
from pipeline.report.formats import estimate
from pipeline.world.generate import is_spec, parse_spec
from pipeline.world.pictures import N_PHYSICAL_OBSTACLES

#: The settings from no DSS to the full DSS: (method, learn_from), the reach growing.
SETTINGS = (
    ("fewshot", "all"),
    ("fewshot_dss", "same_picture"),
    ("fewshot_dss", "same_object"),
    ("fewshot_dss", "same_category"),
    ("fewshot_dss", "all"),
)
#: The source each step between consecutive settings adds (module docstring).
SOURCES = (
    "same face",
    "other faces of the obstacle",
    "the category's other obstacle",
    "other categories",
)


def learn_from(cell: Cell) -> str:
    """The cell's ``learn_from`` (``all`` when its recogniser has none)."""
    return str(((cell.config or {}).get("recogniser") or {}).get("learn_from", "all"))


def by_layout(exp: Experiment, label_of) -> dict[tuple[str, str], dict[tuple[str, str], Cell]]:
    """The cells on generated layouts by (layout, recogniser), then by setting (method,
    ``learn_from``); ``label_of(cell)`` names the recogniser (without its ``learn_from``)."""
    found: dict[tuple[str, str], dict[tuple[str, str], Cell]] = {}
    for cell in exp.cells.values():
        if is_spec(cell.maze):
            key = (cell.maze, label_of(cell))
            found.setdefault(key, {})[(cell.method, learn_from(cell))] = cell
    return found


def layout_row(label: str, maze: str) -> dict:
    """The first columns of a layout's row: the recogniser, r and the layout."""
    return {
        "recogniser": label,
        "r": parse_spec(maze).obstacles / N_PHYSICAL_OBSTACLES,
        "layout": maze,
    }


def source_rows(exp: Experiment, label_of) -> pd.DataFrame:
    """One row per (layout, recogniser) that has all five settings: r, and each source's gain (the
    layout's mean over run seeds of the paired step) and the whole gain (``label_of``:
    :func:`by_layout`)."""
    rows = []
    for (maze, label), cells in by_layout(exp, label_of).items():
        if set(SETTINGS) <= set(cells):
            runs = [cells[s].collisions_by_run() for s in SETTINGS]
            steps = [(a - b).mean() for a, b in pairwise(runs)]
            whole = {"whole gain": (runs[0] - runs[-1]).mean()}
            rows.append(layout_row(label, maze) | dict(zip(SOURCES, steps)) | whole)
    return pd.DataFrame(rows)


def split_table(df: pd.DataFrame, resamples: int, seed: int) -> tuple[list[dict], dict]:
    """Per recogniser and r: the whole gain and each source's gain and share of it, with 95%
    bootstrap intervals over layouts; and the numbers (estimate, low, high) by recogniser, r and
    source for the text."""
    rng = np.random.default_rng(seed)
    columns = [*SOURCES, "whole gain"]
    rows, numbers = [], {}
    for (label, r), g in df.groupby(["recogniser", "r"], sort=True):
        values = g[columns].to_numpy()
        boot = values[rng.integers(0, len(g), (resamples, len(g)))].mean(axis=1)
        point = values.mean(axis=0)
        lo, hi = np.quantile(boot, [0.025, 0.975], axis=0)
        row = {"recogniser": label, "r": f"{r:g}", "layouts": len(g)}
        row["whole DSS gain [95% CI]"] = estimate(point[-1], lo[-1], hi[-1])
        for k, source in enumerate(SOURCES):
            numbers[(label, r, source)] = (point[k], lo[k], hi[k])
            share = 100 * point[k] / point[-1] if point[-1] else np.nan
            row[f"{source} [95% CI]"] = f"{estimate(point[k], lo[k], hi[k])} ({share:.0f}%)"
        numbers[(label, r, "whole gain")] = (point[-1], lo[-1], hi[-1])
        rows.append(row)
    return rows, numbers


def sources_section(rep, exp: Experiment, df: pd.DataFrame, resamples: int, seed: int) -> None:
    """The split's table and a sentence on the smallest r (module docstring) from the rows of
    :func:`source_rows` (``df``: not empty)."""
    rows, numbers = split_table(df, resamples, seed)
    rep.table(
        f"{exp.folder}_sources",
        pd.DataFrame(rows),
        "The DSS gain split by where the substituted picture comes from (collisions per run; "
        "`learn_from`: each step lets a query see one more source, paired on each layout's run "
        "seeds; the steps sum to the whole gain). 95% bootstrap intervals over layouts "
        f"({resamples} resamples, seed {seed}); in brackets after them, the share of the whole gain.",
    )
    label, r = df.sort_values("r").iloc[0][["recogniser", "r"]]
    whole = numbers[(label, r, "whole gain")]
    parts = "; ".join(f"{source} {estimate(*numbers[(label, r, source)])}" for source in SOURCES)
    rep.add(
        f"**Where the gain comes from.** At r = {r:g} the {label}'s DSS gain of {estimate(*whole)} "
        f"collisions per run splits into: {parts}. The category's "
        "two obstacles are two different objects, so the third step is what a picture of one chair "
        "teaches about another.\n"
    )
