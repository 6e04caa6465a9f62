"""One report section per recorded experiment, as its ``report:`` block says
(:class:`~pipeline.report.spec.ReportSpec`; ``docs/extending.md`` "Adding an experiment").

Kinds: ``default`` (a table of collisions per run with 95% bootstrap intervals, learning curves with
95% bands, the support set's query accuracy), ``bars`` (the same with a bar chart), ``long_term``
(the runs are consecutive experiments of one robot) and ``by_maze`` (one row per group of cells,
one column per maze, ours beside the paper's). A ``path`` block adds a section with the learned
path before the experiment's own. Tables and figures are named after the experiment's folder:
``tables/<folder>.md|csv``, ``figures/<folder>_collisions.png``, ``<folder>_learning_curves.png``
(its data ``tables/<folder>_learning_curves.csv``: per row key the mean and ``_ci_low``/``_ci_high``
by episode), ``<folder>_support_accuracy.png``, ``<folder>_long_term.png``, ``<folder>_path.png``;
``by_maze`` adds ``_<maze>`` to the figures and writes ``tables/<folder>_data.csv``.

``rep`` is the report being written (:class:`pipeline.report.build.Report`): ``add``, ``table``,
``figure`` and ``out``.
"""
from __future__ import annotations

import re

import numpy as np
import pandas as pd

from pipeline.records import read_records
from pipeline.report import figures as F
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.spec import Row
from pipeline.report.stats import describe, fmt, mean_band

COLLISIONS = "collisions (mean ± s.d. [95% CI])"


def section(rep, exp: Experiment) -> list[str]:
    """Write the experiment's section(s); returns what is not in the report (``folder/cell``)."""
    missing = [f"{exp.folder}/{c}" for c in exp.missing]
    if exp.spec.path is not None and not path_section(rep, exp):
        missing.append(f"{exp.folder}: {exp.spec.path.title} (no records of {', '.join(exp.spec.path.cells)})")
    title = exp.spec.title or f"Experiment {exp.name}"
    if exp.folder != exp.name:
        title += f" (records in `{exp.folder}`)"
    text = f"## {title}\n"
    if exp.spec.claim:
        text += f"\nPaper: {exp.spec.claim}\n"
    for note in exp.notes:
        text += f"\n{note}\n"
    rep.add(text)
    KINDS[exp.spec.kind](rep, exp)
    return missing


# ------------------------------------------------------------------------------------ pooling
def pooled(cells: list[Cell], what) -> np.ndarray:
    """The (runs, x) arrays ``what(cell)`` of ``cells`` stacked (padded with NaN); the rows of
    cells whose ``what`` is None are left out."""
    arrays = [a for a in (what(c) for c in cells) if a is not None]
    if not arrays:
        return np.empty((0, 0))
    width = max(a.shape[1] for a in arrays)
    return np.vstack([np.pad(a.astype(float), ((0, 0), (0, width - a.shape[1])), constant_values=np.nan)
                      for a in arrays])


def collisions(cells: list[Cell]) -> np.ndarray:
    return np.concatenate([c.collisions_per_run() for c in cells])


def convergence(cells: list[Cell]) -> list[int | None]:
    return sum((c.converged_episode() for c in cells), [])


def pool_note(rows: list[tuple[Row, list[Cell]]], per_maze: bool = False) -> str:
    """Which rows pool several cells (for a table's caption)."""
    parts = []
    for row, cells in rows:
        if per_maze:
            counts = sorted({sum(c.maze == m for c in cells) for m in {c.maze for c in cells}})
            if counts[-1] > 1:
                each = f"{counts[0]}" if len(counts) == 1 else f"{counts[0]}-{counts[-1]}"
                parts.append(f"row '{row.label}' pools the runs of {each} cells per maze")
        elif len(cells) > 1:
            parts.append(f"row '{row.label}' pools the runs of {', '.join(c.name for c in cells)}")
    return (" The " + "; the ".join(parts) + ".") if parts else ""


def safe(name: str) -> str:
    """A maze name (or a layout file's name) as part of a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


# ------------------------------------------------------------------------------------ parts
def collision_row(exp: Experiment, row: Row, cells: list[Cell], show: tuple[str, ...]) -> dict:
    """A table row: the label, the columns of ``show`` (``method``, ``maze``), the collisions per
    run and the convergence of the row's runs, the paper's figure if the block gives any."""
    d = describe(collisions(cells))
    out = {exp.spec.row_header: row.label}
    for column in show:
        out[column] = ", ".join(dict.fromkeys(getattr(c, column) for c in cells))
    out.update({"runs": d["n"], COLLISIONS: fmt(d)})
    conv = convergence(cells)
    if conv:
        ok = [c for c in conv if c is not None]
        out["converged runs"] = f"{len(ok)}/{len(conv)}"
        out["converged episode (mean)"] = f"{np.mean(ok):.0f}" if ok else "not converged"
    if any(r.paper for r, _ in exp.rows()):
        out["paper"] = ", ".join(row.paper.get(m, "") for m in dict.fromkeys(c.maze for c in cells))
    return out


def curves_part(rep, exp: Experiment, rows: list[tuple[Row, list[Cell]]], maze: str | None = None,
                table: dict | None = None) -> None:
    """Learning curves of ``rows``: collisions per episode, mean over runs with a 95% band; their
    data go to ``table`` (column -> values) when given, else to ``tables/<folder>_learning_curves.csv``."""
    series = [(row, a) for row, cells in rows if (a := pooled(cells, Cell.collisions_by_episode)).size]
    if not series:
        return
    own = table is None
    table = {} if own else table
    for row, a in series:
        mean, lo, hi = mean_band(a)
        key = row.key if maze is None else f"{row.key}_{safe(maze)}"
        table.update({key: mean, f"{key}_ci_low": lo, f"{key}_ci_high": hi})
    if own:
        write_curves_table(rep, exp, table)
    where = "" if maze is None else f", {maze}"
    name = f"{exp.folder}_learning_curves{'' if maze is None else '_' + safe(maze)}.png"
    n_runs = sorted({a.shape[0] for _, a in series})
    scales = F.curves({row.label: a for row, a in series}, f"Collisions per episode{where}: mean over runs, 95% band",
                      rep.out / "figures" / name)
    rep.figure(f"figures/{name}", f"Learning curves{where}: collisions per episode from episode 0, mean over "
                                  f"{'/'.join(map(str, n_runs))} runs with its 95% t interval shaded"
                                  f"{' (' + scales + ')' if scales else ''}; data: `tables/{exp.folder}_learning_curves.csv`.")


def write_curves_table(rep, exp: Experiment, table: dict) -> None:
    if not table:
        return
    width = max(len(v) for v in table.values())
    cols = {k: np.pad(np.asarray(v, float), (0, width - len(v)), constant_values=np.nan) for k, v in table.items()}
    pd.DataFrame({"episode": np.arange(width), **cols}).to_csv(
        rep.out / "tables" / f"{exp.folder}_learning_curves.csv", index=False, lineterminator="\n", float_format="%.6g")


def support_part(rep, exp: Experiment, rows: list[tuple[Row, list[Cell]]], maze: str | None = None) -> None:
    """The query accuracy of the rows' support sets over the run (rows with a recogniser)."""
    series = {row.label: pooled(cells, Cell.support_accuracy) for row, cells in rows}
    series = {k: a for k, a in series.items() if a.size}
    if not series:
        return
    where = "" if maze is None else f", {maze}"
    name = f"{exp.folder}_support_accuracy{'' if maze is None else '_' + safe(maze)}.png"
    title = f"Query accuracy of the run's support set over the run{where}"
    scales = F.curves(series, title, rep.out / "figures" / name, ylabel="query accuracy of the support set")
    starts = [s for _, cells in rows for c in cells if (s := c.start_accuracy()) is not None]
    rep.figure(f"figures/{name}", f"{title}: mean over runs at the end of each episode, 95% band"
                                  f"{' (' + scales + ')' if scales else ''}; at the start of a run the support set "
                                  f"recognises {100 * np.mean(starts):.1f}% of the query pictures.")


# ------------------------------------------------------------------------------------ kinds
def default_kind(rep, exp: Experiment, bars: bool = False) -> None:
    rows = exp.rows()
    # a method or maze column where they differ between rows and the first column does not say it
    show = tuple(k for k in ("method", "maze") if k != exp.spec.row_header
                 and len({tuple(getattr(c, k) for c in cells) for _, cells in rows}) > 1)
    rep.table(exp.folder, pd.DataFrame([collision_row(exp, r, cells, show) for r, cells in rows]),
              "Collisions per run within the episodes of each run: mean ± s.d. [95% bootstrap CI] over runs."
              + pool_note(rows))
    if bars:
        name = f"{exp.folder}_collisions.png"
        F.bars([r.label for r, _ in rows], [collisions(cells) for _, cells in rows],
               f"{exp.spec.title or exp.name} (ours)", "collisions per run", rep.out / "figures" / name)
        rep.figure(f"figures/{name}", "Collisions per run: mean (bar), s.d. (thin), 95% bootstrap CI (thick), runs (dots).")
    if exp.spec.curves:
        curves_part(rep, exp, rows)
    if exp.spec.support_accuracy:
        support_part(rep, exp, rows)


def bars_kind(rep, exp: Experiment) -> None:
    default_kind(rep, exp, bars=True)


def long_term_kind(rep, exp: Experiment) -> None:
    """The runs of each row are consecutive experiments of one robot (``support=carry``)."""
    rows = exp.rows()
    values = [(row, collisions(cells)) for row, cells in rows]
    table = [{exp.spec.row_header: row.label, COLLISIONS: fmt(describe(v)),
              "after the first experiment": fmt(describe(v[1:])) if len(v) > 1 else ""} for row, v in values]
    rep.table(exp.folder, pd.DataFrame(table), "Collisions per experiment (consecutive runs)." + pool_note(rows))
    name = f"{exp.folder}_long_term.png"
    F.long_term({row.label: v for row, v in values}, [row.key for row, _ in values],
                f"{exp.spec.title or exp.name} (ours)", rep.out / "figures" / name)
    rep.figure(f"figures/{name}", "Collisions of each consecutive experiment; right: mean with 95% bootstrap CI.")
    if exp.spec.curves:
        curves_part(rep, exp, rows)
    if exp.spec.support_accuracy:
        ends = {row.label: a[:, -1] for row, cells in rows if (a := pooled(cells, Cell.support_accuracy)).size}
        if ends:
            name = f"{exp.folder}_support_accuracy.png"
            F.curves(ends, "Query accuracy of the support set at the end of each experiment", rep.out / "figures" / name,
                     ylabel="query accuracy", xlabel="experiment (consecutive runs)")
            rep.figure(f"figures/{name}", "The support set's query accuracy at the end of each consecutive experiment.")


def by_maze_kind(rep, exp: Experiment) -> None:
    """One row per group, one column per maze (in the order the groups name their cells): ours
    (the group's cells on that maze pooled) and the paper's."""
    rows = exp.rows()
    mazes = list(dict.fromkeys(c.maze for _, cells in rows for c in cells))
    with_paper = {m for m in mazes if any(m in r.paper for r, _ in rows)}
    table, data = [], []
    for row, cells in rows:
        line = {exp.spec.row_header: row.label}
        for maze in mazes:
            group = [c for c in cells if c.maze == maze]
            if group:
                d = describe(collisions(group))
                conv = convergence(group)
                converged = sum(x is not None for x in conv)
                text = fmt(d)
                if conv and converged == 0:
                    text += " (not converged)"
                elif conv and converged < len(conv):
                    text += f" ({converged}/{len(conv)} converged)"
                line[f"{maze} ours"] = text
                data.append({"row": row.key, "label": row.label, "maze": maze, "cells": " ".join(c.name for c in group),
                             **d, "converged_runs": converged, "paper": row.paper.get(maze, "")})
            else:
                line[f"{maze} ours"] = ""
            if maze in with_paper:
                line[f"{maze} paper"] = row.paper.get(maze, "")
        table.append(line)
    pd.DataFrame(data).to_csv(rep.out / "tables" / f"{exp.folder}_data.csv", index=False, lineterminator="\n")
    rep.table(exp.folder, pd.DataFrame(table),
              "Mean ± s.d. [95% bootstrap CI] of collisions per run." + pool_note(rows, per_maze=True))
    curves = {}
    for maze in mazes:
        on_maze = [(row, [c for c in cells if c.maze == maze]) for row, cells in rows]
        on_maze = [(row, cells) for row, cells in on_maze if cells]
        if exp.spec.curves:
            curves_part(rep, exp, on_maze, maze, table=curves)
    write_curves_table(rep, exp, curves)
    if exp.spec.support_accuracy:
        for maze in mazes:
            on_maze = [(row, [c for c in cells if c.maze == maze]) for row, cells in rows]
            support_part(rep, exp, [(row, cells) for row, cells in on_maze if cells], maze)


KINDS = {"default": default_kind, "bars": bars_kind, "long_term": long_term_kind, "by_maze": by_maze_kind}


# ------------------------------------------------------------------------------------ path
def path_section(rep, exp: Experiment) -> bool:
    """The learned path of the first recorded cell of ``report.path.cells``: the most common path
    of the runs' last episodes (the paper's Figure 7). False if none of them has records."""
    spec = exp.spec.path
    name = next((n for n in spec.cells if n in exp.cells), None)
    if name is None:
        return False
    cell = exp.cells[name]
    steps = read_records(cell.path, pictures=False).steps
    width = len(cell.layout[0])
    goal = next(r * width + c for r, row in enumerate(cell.layout) for c, ch in enumerate(row) if ch == "G")
    on_path = F.modal_final_path(steps, width, goal)
    figure = f"{exp.folder}_path.png"
    F.optimal_path(cell.layout, cell.obstacles.get(0, []), on_path,
                   f"{spec.title} (ours): {exp.spec.label(name)}, last episode, most common over runs",
                   rep.out / "figures" / figure)
    ours = (f"the most common path of the runs' last episodes ({exp.spec.label(name)}), {len(on_path) - 1} moves"
            if on_path else f"no run's last episode reached the goal ({exp.spec.label(name)})")
    claim = f"Paper: {spec.claim} " if spec.claim else ""
    rep.add(f"## {spec.title}\n\n{claim}Ours: {ours}.\n")
    rep.figure(f"figures/{figure}", f"{spec.title}, ours; obstacles of run 0 coloured by category.")
    return True
