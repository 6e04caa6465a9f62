"""The ``accuracy_curve`` section kind: collisions against the recognition accuracy of a controlled
recogniser (``conf/experiment/accuracy_curve.yaml``: how accurate must recognition be for
few-shot reasoning to pay off?).

What each cell is comes from its records: a cell with a recogniser (its records hold the support
set's query accuracy) is a point of the curve of its method on its maze, at the ``p`` of the
recogniser it ran with (the recorded config's ``recogniser.p``); a cell without one (SSRL, the
shield) is a reference line on its maze. Mazes are ordered by their number of cells. The section:
a figure of the curves (a panel per maze, the Relation Network's measured accuracy as a vertical
line), the break-even accuracies (:func:`~pipeline.stats.break_even`, paired over the run seeds
the cells share) and every point's data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.report import figures_beyond as FB
from pipeline.report.accuracy import query_accuracy
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import (
    PAPER_RECOGNISER,
    method_colour,
    method_name,
    recogniser_colour,
    recogniser_name,
)
from pipeline.stats import break_even, describe, fmt


@dataclass
class Curve:
    """The cells of one method on one maze, by increasing recognition accuracy ``p``."""

    maze: str
    label: str
    levels: np.ndarray
    cells: list[Cell]

    def collisions(self) -> np.ndarray:
        """(levels, runs): collisions per run of each point (run ``i`` of one seed in every cell)."""
        return np.stack([c.collisions_per_run() for c in self.cells])


@dataclass
class Split:
    """An experiment split into curves and references, and what could not be placed."""

    mazes: list[str]
    curves: list[Curve]
    references: dict[tuple[str, str], Cell]  # (maze, method name) -> cell
    notes: list[str]


def recogniser_p(cell: Cell) -> float | None:
    """The ``p`` of the recogniser the cell ran with (its recorded config), or None."""
    p = ((cell.config or {}).get("recogniser") or {}).get("p")
    return None if p is None else float(p)


def split(exp: Experiment) -> Split:
    """Curves (cells with a recogniser, by method and maze) and references (cells without), of
    the report block's ``cells`` if it names any, else of every recorded cell."""
    points: dict[tuple[str, str], dict[float, Cell]] = {}
    references: dict[tuple[str, str], Cell] = {}
    notes = []
    shown = (
        [exp.cells[n] for n in exp.spec.cells if n in exp.cells]
        if exp.spec.cells
        else list(exp.cells.values())
    )
    for cell in shown:
        key = (cell.maze, method_name(cell.info["method"]))
        if not cell.recognises:
            slot, at = references, key
        elif (p := recogniser_p(cell)) is None:
            notes.append(
                f"cell {cell.name}: its recogniser has no accuracy p, so it is not on a curve"
            )
            continue
        else:
            slot, at = points.setdefault(key, {}), p
        if at in slot:
            notes.append(
                f"cell {cell.name} repeats the setting of cell {slot[at].name}, which is shown"
            )
            continue
        slot[at] = cell
    curves = [
        Curve(maze, label, np.array(sorted(by_p)), [by_p[p] for p in sorted(by_p)])
        for (maze, label), by_p in points.items()
    ]
    sizes = {c.maze: len(c.layout) * len(c.layout[0]) for c in shown}
    mazes = sorted(sizes, key=lambda m: (sizes[m], m))
    curves.sort(key=lambda c: (mazes.index(c.maze), c.label))
    ordered = sorted(references, key=lambda key: (mazes.index(key[0]), key[1]))
    return Split(mazes, curves, {key: references[key] for key in ordered}, notes)


def level_text(value: float, levels: np.ndarray) -> str:
    """A break-even level as printed: ``0.5``, ``≤ 0.2`` (the smallest level), ``not reached``."""
    if np.isinf(value):
        return "not reached"
    return f"≤ {value:g}" if value == levels.min() else f"{value:g}"


def break_even_table(parts: Split) -> pd.DataFrame:
    """One row per maze, method and reference: the reference's collisions and the break-even
    accuracy with its 95% interval (:func:`~pipeline.stats.break_even`)."""
    rows = []
    for curve in parts.curves:
        for (maze, reference), cell in parts.references.items():
            if maze != curve.maze:
                continue
            point, low, high = break_even(
                curve.levels, curve.collisions(), cell.collisions_per_run()
            )
            rows.append(
                {
                    "maze": maze,
                    "method": curve.label,
                    "against": reference,
                    "reference collisions (mean ± s.d. [95% CI])": fmt(described(cell)),
                    "break-even p": level_text(point, curve.levels),
                    "95% CI": f"[{level_text(low, curve.levels)}, {level_text(high, curve.levels)}]",
                }
            )
    return pd.DataFrame(rows)


def data_table(parts: Split) -> pd.DataFrame:
    """Every point of every curve and every reference (p: NaN), with the statistics the figure
    shows."""
    points = [
        (c.maze, c.label, p, cell) for c in parts.curves for p, cell in zip(c.levels, c.cells)
    ]
    points += [(maze, label, np.nan, cell) for (maze, label), cell in parts.references.items()]
    return pd.DataFrame(
        [
            {"maze": maze, "method": label, "p": p, "cell": cell.name, **described(cell)}
            for maze, label, p, cell in points
        ]
    )


def described(cell: Cell) -> dict:
    """:func:`~pipeline.stats.describe` of the cell's collisions per run."""
    return describe(cell.collisions_per_run())


#: What a panel draws of a point: the mean and its 95% interval.
BAND = ("mean", "ci_low", "ci_high")


def band(cells: list[Cell]) -> tuple[np.ndarray, ...]:
    """:data:`BAND` of each cell's collisions per run, as arrays in the order of ``cells``."""
    found = [described(cell) for cell in cells]
    return tuple(np.array([d[k] for d in found]) for k in BAND)


def panels(parts: Split) -> list[dict]:
    """The figure's panels (:func:`pipeline.report.figures.accuracy_curves`), one per maze."""
    out = []
    for maze in parts.mazes:
        curves = [c for c in parts.curves if c.maze == maze]
        references = {label: cell for (m, label), cell in parts.references.items() if m == maze}
        shown = [(c.label, c.cells[0]) for c in curves] + list(references.items())
        out.append(
            {
                "title": maze,
                "curves": {c.label: (c.levels, *band(c.cells)) for c in curves},
                "references": {
                    label: tuple(map(described(cell).get, BAND))
                    for label, cell in references.items()
                },
                "colours": {
                    label: colour
                    for label, cell in shown
                    if (colour := method_colour(cell.info["method"]))
                },
            }
        )
    return out


def marker_text(measured: tuple[int, int] | None) -> str:
    """What the figure's caption says of the paper's recogniser's mark (correct, tested pictures)."""
    name = recogniser_name(PAPER_RECOGNISER)
    if measured is None:
        return f"the {name}'s accuracy is not marked (no accuracy study)"
    correct, tested = measured
    return (
        f"the dotted vertical line is the {name}'s query accuracy with the original support set in "
        f"the accuracy study ({correct}/{tested} = {100 * correct / tested:.1f}%; its errors fall on particular "
        "pictures and categories, where p draws them independently)"
    )


def accuracy_curve_kind(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The section (module docstring); the other ``experiments`` are not used: the paper has no
    such experiment."""
    parts = split(exp)
    runs = sorted({len(c.runs()) for c in exp.cells.values()})
    measured = query_accuracy(rep.accuracy_dir) if rep.accuracy_dir is not None else None
    marker = measured[0] / measured[1] if measured else None
    rn = marker_text(measured)
    rep.add(
        "A controlled recogniser (`fixed_accuracy`) recognises each query picture correctly with probability "
        "p, drawn once per picture per run (a picture substituted after a collision is recognised from then on). "
        "Where do few-shot reasoning's collisions fall below those of the methods without a recogniser?"
        + "".join(f"\n\nNote: {n}." for n in parts.notes)
        + "\n"
    )
    name = f"{exp.folder}.png"
    FB.accuracy_curves(
        panels(parts),
        rep.out / "figures" / name,
        marker,
        f"{recogniser_name(PAPER_RECOGNISER)} ({100 * marker:.1f}%)" if marker is not None else "",
        recogniser_colour(PAPER_RECOGNISER),
    )
    rep.figure(
        f"figures/{name}",
        f"Collisions per run against the recognition accuracy p, one panel per maze: mean "
        f"over {'/'.join(map(str, runs))} runs with its 95% bootstrap interval (band); "
        f"the methods without a recogniser as horizontal lines with their intervals; {rn}. "
        f"Data: `tables/{exp.folder}_data.csv`.",
    )
    rep.data(f"{exp.folder}_data", data_table(parts), float_format="%.6g")
    table = break_even_table(parts)
    if len(table):
        table = table.rename(columns={"method": exp.spec.row_header})
        rep.table(
            exp.folder,
            table,
            "Break-even accuracy: the smallest p at which the method's mean collisions per run are at or "
            "below the reference's; 95% CI from 2000 bootstrap resamples of the run seeds (seed 0), paired "
            "across the cells, which share run seeds; its resolution is the grid of p. '≤' marks the smallest "
            "p tried, 'not reached': above the reference at every p tried.",
        )
