"""One report section per recorded experiment, of the kind its ``report:`` block names
(:class:`~pipeline.report.spec.ReportSpec`; the kinds: docs/extending.md). A ``path`` block adds a
section with the learned path before the experiment's own. Tables and figures are named after the
experiment's folder (``tables/<folder>.md|csv``, ``figures/<folder>_collisions.png``...; ``by_maze``
adds ``_<maze>`` to the figures). The parts of a section are in :mod:`pipeline.report.parts`, the
pooling of cells in :mod:`pipeline.report.pooling`, the paper's numbers beside ours in
:mod:`pipeline.report.paper_numbers`. ``rep`` is the report being written
(:class:`pipeline.report.build.Report`).
"""

from __future__ import annotations

from functools import partial

import pandas as pd

from pipeline.records import read_records
from pipeline.report import figures as F
from pipeline.report import learning_curves as LC
from pipeline.report.accuracy_curve import accuracy_curve_kind
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.generalisation import generalisation_section
from pipeline.report.networks import networks_section
from pipeline.report.paper_numbers import PaperValue, paper_values
from pipeline.report.parts import (
    COLLISIONS,
    collision_row,
    curves_part,
    styles_of,
    support_part,
    write_curves_table,
)
from pipeline.report.pooling import collisions, convergence, describe_runs, pool_note, pooled
from pipeline.report.repetition import repetition_section
from pipeline.report.robot import robot_kind
from pipeline.report.spec import Row
from pipeline.stats import describe, fmt


def section(rep, exp: Experiment, experiments: list[Experiment] = ()) -> list[str]:
    """Write the experiment's section(s); ``experiments``: every section of the report (the paper's
    numbers of one may belong to another). Returns what is not in the report (``folder/cell``)."""
    missing = [f"{exp.folder}/{c}" for c in exp.missing]
    if exp.spec.path is not None and not path_section(rep, exp):
        missing.append(
            f"{exp.folder}: {exp.spec.path.title} (no records of {', '.join(exp.spec.path.cells)})"
        )
    title = exp.spec.title or f"Experiment {exp.name}"
    if exp.folder != exp.name:
        title += f" (records in `{exp.folder}`)"
    text = f"## {title}\n"
    if exp.spec.claim:
        text += f"\nPaper: {exp.spec.claim}\n"
    for note in exp.notes:
        text += f"\n{note}\n"
    rep.add(text)
    KINDS[exp.spec.kind](rep, exp, list(experiments))
    return missing


# ------------------------------------------------------------------------------------ kinds
PAPER_NOTE = (
    "The paper prints no numbers for its Figures 8-10; where its Table 3 gives one for the same setting, "
    "the table and the bars show it (a dash on the bar; dashed: the paper's number pools more cells)."
)


def row_marks(rows: list[tuple[Row, list[Cell]]], paper: dict[str, PaperValue]) -> dict:
    """How a figure of the rows marks them: the paper's number of each (None without one) and
    each row's style (:func:`~pipeline.report.parts.styles_of`)."""
    return {"paper": [paper.get(row.key) for row, _ in rows], "styles": styles_of(rows)}


def default_kind(rep, exp: Experiment, experiments: list[Experiment], bars: bool = False) -> None:
    """A table of collisions per run (``bars``: and a bar chart of them), learning curves, the
    support set's accuracy over the run; the paper's numbers beside ours where another section
    gives them (``experiments``: every section)."""
    rows, paper = exp.rows(), paper_values(exp, experiments)
    rep.table(
        exp.folder,
        pd.DataFrame([collision_row(exp, r, cells, paper) for r, cells in rows]),
        "Collisions per run within the episodes of each run: mean ± s.d. [95% bootstrap CI] over runs."
        + pool_note(rows)
        + (" " + PAPER_NOTE if paper else ""),
    )
    if bars:
        name = f"{exp.folder}_collisions.png"
        axis = F.bars(
            [r.label for r, _ in rows],
            [collisions(cells) for _, cells in rows],
            f"{exp.spec.title or exp.name} (ours)",
            "collisions per run",
            rep.out / "figures" / name,
            **row_marks(rows, paper),
        )
        rep.figure(
            f"figures/{name}",
            "Collisions per run: mean (bar; its value under the name), s.d. (thin), 95% bootstrap "
            "CI (thick), runs (dots)"
            + ("; the paper's number as a black dash" if paper else "")
            + (f"; {axis} (diagonal marks), so the lower bars keep their scale" if axis else "")
            + ".",
        )
    if exp.spec.curves is not False:
        write_curves_table(rep, exp, curves_part(rep, exp, rows))
    if exp.spec.support_accuracy is not False:
        support_part(rep, exp, rows)


def long_term_kind(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The runs of each row are consecutive experiments of one robot (``support=carry``)."""
    rows, paper = exp.rows(), paper_values(exp, experiments)
    values = [(row, collisions(cells)) for row, cells in rows]
    table = [
        {
            exp.spec.row_header: row.label,
            COLLISIONS: fmt(describe(v)),
            "after the first experiment": fmt(describe(v[1:])) if len(v) > 1 else "",
            **({"paper": paper[row.key].text() if row.key in paper else ""} if paper else {}),
        }
        for row, v in values
    ]
    rep.table(
        exp.folder,
        pd.DataFrame(table),
        "Collisions per experiment (consecutive runs)."
        + pool_note(rows)
        + (" " + PAPER_NOTE if paper else ""),
    )
    name = f"{exp.folder}_long_term.png"
    F.long_term(
        {row.label: v for row, v in values},
        f"{exp.spec.title or exp.name} (ours)",
        rep.out / "figures" / name,
        **row_marks(rows, paper),
    )
    rep.figure(
        f"figures/{name}",
        "Collisions of each consecutive experiment (numbered from 1); right: mean with 95% "
        "bootstrap CI" + ("; the paper's number as a black dash" if paper else "") + ".",
    )
    if exp.spec.curves is not False:
        write_curves_table(rep, exp, curves_part(rep, exp, rows))
    if exp.spec.support_accuracy is not False:
        ends = {
            row.label: a[:, -1]
            for row, cells in rows
            if (a := pooled(cells, Cell.support_accuracy)).size
        }
        if ends:
            name = f"{exp.folder}_support_accuracy.png"
            LC.curves(
                ends,
                "Query accuracy of the support set at the end of each experiment",
                rep.out / "figures" / name,
                ylabel="query accuracy",
                xlabel="experiment (consecutive runs, from 1)",
                styles=styles_of(rows),
                first=1,
            )
            rep.figure(
                f"figures/{name}",
                "The support set's query accuracy at the end of each consecutive experiment "
                "(one robot's experiments in order: one value each, no band).",
            )


def by_maze_kind(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """One row per group, one column per maze (in the order the groups name their cells): ours
    (the group's cells on that maze pooled) and the paper's (the group's own ``paper``)."""
    rows = exp.rows()
    mazes = list(dict.fromkeys(c.maze for _, cells in rows for c in cells))
    with_paper = {m for m in mazes if any(m in r.paper for r, _ in rows)}
    table, data = [], []
    for row, cells in rows:
        line = {exp.spec.row_header: row.label}
        for maze in mazes:
            group = [c for c in cells if c.maze == maze]
            if group:
                d = describe_runs(group)
                conv = convergence(group)
                converged = sum(x is not None for x in conv)
                text = fmt(d)
                if conv and converged == 0:
                    text += " (not converged)"
                elif conv and converged < len(conv):
                    text += f" ({converged}/{len(conv)} converged)"
                line[f"{maze} ours"] = text
                data.append(
                    {
                        "row": row.key,
                        "label": row.label,
                        "maze": maze,
                        "cells": " ".join(c.name for c in group),
                        **d,
                        "converged_runs": converged,
                        "paper": row.paper.get(maze, ""),
                    }
                )
            else:
                line[f"{maze} ours"] = ""
            if maze in with_paper:
                line[f"{maze} paper"] = row.paper.get(maze, "")
        table.append(line)
    rep.data(f"{exp.folder}_data", pd.DataFrame(data))
    rep.table(
        exp.folder,
        pd.DataFrame(table),
        "Mean ± s.d. [95% bootstrap CI] of collisions per run." + pool_note(rows, per_maze=True),
    )
    on_maze = {
        maze: [(row, on) for row, cells in rows if (on := [c for c in cells if c.maze == maze])]
        for maze in mazes
    }
    curves = []
    for maze in mazes if exp.spec.curves is not False else []:
        here = curves_part(rep, exp, on_maze[maze], maze)
        write_curves_table(rep, exp, here, maze)  # the DVC plot of this maze
        curves += here
    write_curves_table(rep, exp, curves)
    for maze in mazes if exp.spec.support_accuracy is not False else []:
        support_part(rep, exp, on_maze[maze], maze)


#: Each kind's section, called with the report, the experiment and every experiment of the report
#: (the paper's numbers of one may belong to another).
KINDS = {
    "default": default_kind,
    "bars": partial(default_kind, bars=True),
    "long_term": long_term_kind,
    "by_maze": by_maze_kind,
    "accuracy_curve": accuracy_curve_kind,
    "generalisation": generalisation_section,
    "repetition": repetition_section,
    "robot": robot_kind,
    "networks": networks_section,
}


# ------------------------------------------------------------------------------------ path
def path_section(rep, exp: Experiment) -> bool:
    """The learned path of the first recorded cell of ``report.path.cells``: the most common path
    of the runs' last episodes (the paper's Figure 7). False if none of them has records."""
    spec = exp.spec.path
    name = next((n for n in spec.cells if n in exp.cells), None)
    if name is None:
        return False
    cell = exp.cells[name]
    label = next((row.label for row, cells in exp.rows() if cell in cells), name)
    steps = read_records(cell.path, pictures=False).steps
    width = len(cell.layout[0])
    goal = next(
        r * width + c for r, row in enumerate(cell.layout) for c, ch in enumerate(row) if ch == "G"
    )
    on_path = F.modal_final_path(steps, width, goal)
    figure = f"{exp.folder}_path.png"
    F.optimal_path(
        cell.layout,
        cell.obstacles.get(0, []),
        on_path,
        f"{spec.title} (ours): {label}, last episode, most common over runs",
        rep.out / "figures" / figure,
    )
    ours = (
        f"the most common path of the runs' last episodes ({label}), {len(on_path) - 1} moves"
        if on_path
        else f"no run's last episode reached the goal ({label})"
    )
    claim = f"Paper: {spec.claim} " if spec.claim else ""
    rep.add(f"## {spec.title}\n\n{claim}Ours: {ours}.\n")
    rep.figure(f"figures/{figure}", f"{spec.title}, ours; obstacles of run 0 coloured by category.")
    return True
