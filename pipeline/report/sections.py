"""One report section per recorded experiment, as its ``report:`` block says
(:class:`~pipeline.report.spec.ReportSpec`; ``docs/extending.md`` "Adding an experiment").

Kinds: ``default`` (a table of collisions per run with 95% bootstrap intervals, learning curves with
95% bands, the support set's query accuracy), ``bars`` (the same with a bar chart), ``long_term``
(the runs are consecutive experiments of one robot), ``by_maze`` (one row per group of cells,
one column per maze, ours beside the paper's) and ``accuracy_curve`` (collisions against a
controlled recogniser's accuracy: :mod:`pipeline.report.accuracy_curve`) and ``generalisation``
(the paper's claims over generated layouts: :mod:`pipeline.report.generalisation`). A ``path`` block adds
a section with the learned path before the experiment's own. Tables and figures are named after
the experiment's folder: ``tables/<folder>.md|csv``, ``figures/<folder>_collisions.png``,
``<folder>_learning_curves.png`` (its data ``tables/<folder>_learning_curves.csv``, long format:
``series`` (the row's name; with `` (<maze>)`` in ``by_maze``), ``key``, ``episode``, ``mean``,
``ci_low``, ``ci_high``; dvc.yaml's plots colour by ``series``), ``<folder>_support_accuracy.png``,
``<folder>_long_term.png``, ``<folder>_path.png``; ``by_maze`` adds ``_<maze>`` to the figures and
writes ``tables/<folder>_data.csv``.

Rows are named from their cells (:mod:`pipeline.report.names`). A row that pools cells (Table 3's
four substitution ways) counts each run seed once in its intervals: the cells share run seeds, so
its per-episode curve averages the cells per seed and its CI resamples seeds. Where another
section prints the paper's number for the same setting (Table 3's 5x5 column for Figures 8-10),
the tables and bar charts show it beside ours (:func:`paper_values`).

``rep`` is the report being written (:class:`pipeline.report.build.Report`): ``add``, ``table``,
``figure``, ``out`` and ``accuracy_dir``.
"""

from __future__ import annotations

import json
import re
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.records import read_records
from pipeline.report import figures as F
from pipeline.report.accuracy_curve import accuracy_curve_kind
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import row_colours, settings
from pipeline.report.spec import PER_CELL_KINDS, Row
from pipeline.report.stats import describe, fmt, mean_band

COLLISIONS = "collisions (mean ± s.d. [95% CI])"


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
    per_cell = exp.spec.kind in PER_CELL_KINDS  # no rows to put the paper's numbers beside
    KINDS[exp.spec.kind](rep, exp, {} if per_cell else paper_values(exp, experiments))
    return missing


# ------------------------------------------------------------------------------------ pooling
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


@dataclass
class PaperValue:
    """The paper's number for a row, printed in another section for the same setting."""

    value: str  # as printed
    source: str  # the section's name ("Table 3")
    pools: str = ""  # what the paper's number pools beyond the row ("ways 1-4 pooled")

    def text(self) -> str:
        return f"{self.value} ({self.source}{', ' + self.pools if self.pools else ''})"

    def number(self) -> float | None:
        try:
            return float(self.value)
        except ValueError:
            return None


def setting_key(cell: Cell) -> str:
    """What a cell ran, except its substitution way: method, maze, episodes, support set and
    recogniser (JSON, to compare cells of different experiments)."""
    info = cell.info
    recogniser = (info.get("recogniser") or {}).get("kind")
    return json.dumps(
        [
            info["method"],
            info["maze"],
            (cell.config or {}).get("episodes"),
            recogniser,
            info.get("support") if recogniser else None,
        ],
        sort_keys=True,
    )


def way(cell: Cell):
    return cell.info.get("substitution") if cell.info["method"].get("dynamic_support") else None


def paper_for(cells: list[Cell], experiments: list[Experiment]) -> PaperValue | None:
    """The paper's number for ``cells`` (one setting, any substitution ways) from a group of any
    section that gives one for the same :func:`setting_key` on their maze, the group's ways
    including theirs; None if there is none."""
    keys, ways = {setting_key(c) for c in cells}, {way(c) for c in cells}
    if len(keys) != 1:
        return None
    for other in experiments:
        if not any(group.paper for group in other.spec.groups):
            continue  # only groups carry the paper's numbers (and naming 2,100 rows is slow)
        source = (other.spec.title or other.name).split(":")[0]
        for group, group_cells in other.rows():
            for maze, value in group.paper.items():
                on = [c for c in group_cells if c.maze == maze]
                if on and {setting_key(c) for c in on} == keys and ways <= {way(c) for c in on}:
                    wider = sorted({way(c) for c in on} - {None})
                    if not wider or ways == set(wider):
                        return PaperValue(str(value), source)
                    together = (
                        f"{wider[0]}-{wider[-1]}"
                        if wider == list(range(wider[0], wider[-1] + 1))
                        else ", ".join(map(str, wider))
                    )
                    return PaperValue(str(value), source, f"ways {together} pooled")
    return None


def paper_values(exp: Experiment, experiments: list[Experiment]) -> dict[str, PaperValue]:
    """By row key of ``exp`` (rows without their own ``paper``): :func:`paper_for` the row's
    cells. The paper prints no numbers for Figures 8-10; its Table 3 does for their 5x5 setting
    (the DSS row as the mean of the four ways)."""
    found = {row.key: paper_for(cells, experiments) for row, cells in exp.rows() if not row.paper}
    return {key: value for key, value in found.items() if value is not None}


def colours_of(rows: list[tuple[Row, list[Cell]]]) -> dict[str, str]:
    """The rows' colours by label where each row is one declared method (its colour in every
    figure: :func:`~pipeline.report.names.row_colours`); empty otherwise."""
    found = row_colours([[c.info for c in cells] for _, cells in rows])
    return {rows[i][0].label: colour for i, colour in found.items()}


def safe(name: str) -> str:
    """A maze name (or a layout file's name) as part of a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


# ------------------------------------------------------------------------------------ parts
def collision_row(
    exp: Experiment, row: Row, cells: list[Cell], paper: dict[str, PaperValue]
) -> dict:
    """A table row: the row's name, the collisions per run and the convergence of its runs, the
    paper's number where there is one (``paper``: by row key)."""
    d = describe_runs(cells)
    out = {exp.spec.row_header: row.label, "runs": d["n"], COLLISIONS: fmt(d)}
    conv = convergence(cells)
    if conv:
        ok = [c for c in conv if c is not None]
        out["converged runs"] = f"{len(ok)}/{len(conv)}"
        out["converged episode (mean)"] = f"{np.mean(ok):.0f}" if ok else "not converged"
    if paper:
        out["paper"] = paper[row.key].text() if row.key in paper else ""
    return out


def curves_part(
    rep,
    exp: Experiment,
    rows: list[tuple[Row, list[Cell]]],
    maze: str | None = None,
    table: dict | None = None,
) -> None:
    """Learning curves of ``rows``: collisions per episode, mean over run seeds with a 95% band;
    their data go to ``table`` (a list of frames) when given, else to
    ``tables/<folder>_learning_curves.csv``."""
    series = [
        (row, a) for row, cells in rows if (a := pooled(cells, Cell.collisions_by_episode)).size
    ]
    if not series:
        return
    own = table is None
    table = [] if own else table
    for row, a in series:
        mean, lo, hi = mean_band(a)
        name, key = (
            (row.label, row.key)
            if maze is None
            else (f"{row.label} ({maze})", f"{row.key}_{safe(maze)}")
        )
        table.append(
            pd.DataFrame(
                {
                    "series": name,
                    "key": key,
                    "episode": np.arange(mean.size),
                    "mean": mean,
                    "ci_low": lo,
                    "ci_high": hi,
                }
            )
        )
    if own:
        write_curves_table(rep, exp, table)
    where = "" if maze is None else f", {maze}"
    name = f"{exp.folder}_learning_curves{'' if maze is None else '_' + safe(maze)}.png"
    n_runs = sorted({a.shape[0] for _, a in series})
    scales = F.curves(
        {row.label: a for row, a in series},
        f"Collisions per episode{where}: mean over runs, 95% band",
        rep.out / "figures" / name,
        colours=colours_of(rows),
    )
    pooled_rows = (
        " (a row that pools cells: their mean per seed)" if any(len(c) > 1 for _, c in rows) else ""
    )
    scales = f" ({scales})" if scales else ""
    rep.figure(
        f"figures/{name}",
        f"Learning curves{where}: collisions per episode from episode 0, mean over "
        f"{'/'.join(map(str, n_runs))} run seeds{pooled_rows} with its 95% t interval shaded"
        f"{scales}; data: `tables/{exp.folder}_learning_curves.csv`.",
    )


def write_curves_table(rep, exp: Experiment, frames: list[pd.DataFrame]) -> None:
    if frames:
        pd.concat(frames, ignore_index=True).to_csv(
            rep.out / "tables" / f"{exp.folder}_learning_curves.csv",
            index=False,
            lineterminator="\n",
            float_format="%.6g",
        )


def support_part(
    rep, exp: Experiment, rows: list[tuple[Row, list[Cell]]], maze: str | None = None
) -> None:
    """The query accuracy of the rows' support sets over the run (rows with a recogniser)."""
    series = {row.label: pooled(cells, Cell.support_accuracy) for row, cells in rows}
    series = {k: a for k, a in series.items() if a.size}
    if not series:
        return
    where = "" if maze is None else f", {maze}"
    name = f"{exp.folder}_support_accuracy{'' if maze is None else '_' + safe(maze)}.png"
    title = f"Query accuracy of the run's support set over the run{where}"
    scales = F.curves(
        series,
        title,
        rep.out / "figures" / name,
        ylabel="query accuracy of the support set",
        colours=colours_of(rows),
    )
    starts = {
        row.label: [s for c in cells if (s := c.start_accuracy()) is not None]
        for row, cells in rows
    }
    rep.figure(
        f"figures/{name}",
        f"{title}: mean over run seeds at the end of each episode, 95% t band"
        f"{' (' + scales + ')' if scales else ''}{start_accuracy_note(starts)}.",
    )


def start_accuracy_note(starts: dict[str, list[float]]) -> str:
    """What the rows' original support sets recognise at the start of a run: one figure when the
    rows agree (one recogniser), else one per row (rows with other recognisers differ); "" without any."""
    means = {label: float(np.mean(v)) for label, v in starts.items() if v}
    shown = {f"{100 * m:.1f}%" for m in means.values()}
    if not means:
        return ""
    if len(shown) == 1:
        return f"; at the start of a run the support set recognises {shown.pop()} of the query pictures"
    return (
        "; at the start of a run the support set recognises "
        + ", ".join(f"{100 * m:.1f}% ({label})" for label, m in means.items())
        + " of the query pictures"
    )


# ------------------------------------------------------------------------------------ kinds
PAPER_NOTE = (
    "The paper prints no numbers for its Figures 8-10; where its Table 3 gives one for the same setting, "
    "the table and the bars show it (a dash on the bar; dashed: the paper's number pools more cells)."
)


def default_kind(rep, exp: Experiment, paper: dict[str, PaperValue], bars: bool = False) -> None:
    rows = exp.rows()
    rep.table(
        exp.folder,
        pd.DataFrame([collision_row(exp, r, cells, paper) for r, cells in rows]),
        "Collisions per run within the episodes of each run: mean ± s.d. [95% bootstrap CI] over runs."
        + pool_note(rows)
        + (" " + PAPER_NOTE if paper else ""),
    )
    if bars:
        name = f"{exp.folder}_collisions.png"
        F.bars(
            [r.label for r, _ in rows],
            [collisions(cells) for _, cells in rows],
            f"{exp.spec.title or exp.name} (ours)",
            "collisions per run",
            rep.out / "figures" / name,
            paper=[paper.get(r.key) for r, _ in rows],
        )
        rep.figure(
            f"figures/{name}",
            "Collisions per run: mean (bar), s.d. (thin), 95% bootstrap CI (thick), runs "
            "(dots)" + ("; the paper's number in red" if paper else "") + ".",
        )
    if exp.spec.curves is not False:
        curves_part(rep, exp, rows)
    if exp.spec.support_accuracy is not False:
        support_part(rep, exp, rows)


def bars_kind(rep, exp: Experiment, paper: dict[str, PaperValue]) -> None:
    default_kind(rep, exp, paper, bars=True)


def long_term_kind(rep, exp: Experiment, paper: dict[str, PaperValue]) -> None:
    """The runs of each row are consecutive experiments of one robot (``support=carry``)."""
    rows = exp.rows()
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
        paper=[paper.get(row.key) for row, _ in values],
    )
    rep.figure(
        f"figures/{name}",
        "Collisions of each consecutive experiment; right: mean with 95% bootstrap CI"
        + ("; the paper's number in red" if paper else "")
        + ".",
    )
    if exp.spec.curves is not False:
        curves_part(rep, exp, rows)
    if exp.spec.support_accuracy is not False:
        ends = {
            row.label: a[:, -1]
            for row, cells in rows
            if (a := pooled(cells, Cell.support_accuracy)).size
        }
        if ends:
            name = f"{exp.folder}_support_accuracy.png"
            F.curves(
                ends,
                "Query accuracy of the support set at the end of each experiment",
                rep.out / "figures" / name,
                ylabel="query accuracy",
                xlabel="experiment (consecutive runs)",
            )
            rep.figure(
                f"figures/{name}",
                "The support set's query accuracy at the end of each consecutive experiment "
                "(one robot's experiments in order: one value each, no band).",
            )


def by_maze_kind(rep, exp: Experiment, paper: dict[str, PaperValue]) -> None:
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
    pd.DataFrame(data).to_csv(
        rep.out / "tables" / f"{exp.folder}_data.csv", index=False, lineterminator="\n"
    )
    rep.table(
        exp.folder,
        pd.DataFrame(table),
        "Mean ± s.d. [95% bootstrap CI] of collisions per run." + pool_note(rows, per_maze=True),
    )
    curves = []
    for maze in mazes:
        on_maze = [(row, [c for c in cells if c.maze == maze]) for row, cells in rows]
        on_maze = [(row, cells) for row, cells in on_maze if cells]
        if exp.spec.curves is not False:
            curves_part(rep, exp, on_maze, maze, table=curves)
    write_curves_table(rep, exp, curves)
    if exp.spec.support_accuracy is not False:
        for maze in mazes:
            on_maze = [(row, [c for c in cells if c.maze == maze]) for row, cells in rows]
            support_part(rep, exp, [(row, cells) for row, cells in on_maze if cells], maze)


def generalisation_kind(rep, exp: Experiment, paper: dict[str, PaperValue]) -> None:
    """:mod:`pipeline.report.generalisation` (imported here: it checks claims with
    :mod:`pipeline.report.claims`, which imports this module)."""
    from pipeline.report.generalisation import generalisation_section

    generalisation_section(rep, exp)


KINDS = {
    "default": default_kind,
    "bars": bars_kind,
    "long_term": long_term_kind,
    "by_maze": by_maze_kind,
    "accuracy_curve": accuracy_curve_kind,
    "generalisation": generalisation_kind,
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
