"""Cells pooled into a report row. The cells of an experiment share run seeds (run ``r`` has the
same obstacles and random streams in every cell), so a row that pools cells (Table 3's four
substitution ways) averages them per seed before its curve's band and its bootstrap interval:
each seed counts once. Cells with other run seeds are stacked as independent runs."""

from __future__ import annotations

import warnings

import numpy as np

from pipeline.report.experiments import Cell
from pipeline.report.names import settings
from pipeline.report.spec import Row
from pipeline.stats import describe


def pooled(cells: list[Cell], what) -> np.ndarray:
    """(runs, x): the arrays ``what(cell)`` of ``cells`` (padded with NaN), averaged over the cells
    per run seed, so that each seed counts once in a band; cells whose ``what`` is None are left
    out. Cells with other run seeds (another seed or run count) are stacked as independent runs."""
    found = [(c, a) for c in cells if (a := what(c)) is not None]
    if not found:
        return np.empty((0, 0))
    width = max(a.shape[1] for _, a in found)
    arrays = [
        np.pad(a.astype(float), ((0, 0), (0, width - a.shape[1])), constant_values=np.nan)
        for _, a in found
    ]
    if len(found) > 1 and same_seeds([c for c, _ in found]):
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an episode no cell reached: NaN
            return np.nanmean(np.stack(arrays), axis=0)
    return np.vstack(arrays)


def same_seeds(cells: list[Cell]) -> bool:
    """Whether run ``r`` of every cell has the same seed (one seed, the same run indices)."""
    first = cells[0]
    return all(c.seed == first.seed and np.array_equal(c.runs(), first.runs()) for c in cells)


def collisions(cells: list[Cell]) -> np.ndarray:
    return np.concatenate([c.collisions_per_run() for c in cells])


def describe_runs(cells: list[Cell]) -> dict:
    """:func:`describe` of the collisions per run of ``cells``; pooled cells that share run seeds
    get a CI that resamples seeds."""
    clusters = (
        np.concatenate([c.runs() for c in cells]) if len(cells) > 1 and same_seeds(cells) else None
    )
    return describe(collisions(cells), clusters)


def convergence(cells: list[Cell]) -> list[int | None]:
    return [e for c in cells for e in c.converged_episode()]


def pool_note(rows: list[tuple[Row, list[Cell]]], per_maze: bool = False) -> str:
    """Which rows pool several cells (for a table's caption)."""
    parts = []
    for row, cells in rows:
        if per_maze:
            counts = sorted({sum(c.maze == m for c in cells) for m in {c.maze for c in cells}})
            if counts[-1] > 1:
                each = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
                parts.append(
                    f"row '{row.label}' pools the runs of {each} cells per maze ({pooled_settings(cells)})"
                )
        elif len(cells) > 1:
            parts.append(
                f"row '{row.label}' pools the runs of {len(cells)} cells ({pooled_settings(cells)})"
            )
    if not parts:
        return ""
    return (
        " The "
        + "; the ".join(parts)
        + "; its interval resamples run seeds, which the pooled cells share "
        "(each seed's runs averaged)."
    )


def pooled_settings(cells: list[Cell]) -> str:
    """What differs between pooled cells besides the maze, in words (``way 1, way 2``)."""
    words = [settings(c.info) for c in cells]
    keys = [k for k in words[0] if k != "maze" and len({w.get(k) for w in words}) > 1]
    return (
        ", ".join(dict.fromkeys(" ".join(w[k] for k in keys) for w in words)) or "the same setting"
    )
