"""The parts every section kind is built of: a row of the collisions table, the learning curves
(collisions per episode, mean over run seeds with a 95% band, and their long-format table), the
support set's query accuracy over the run. ``rep`` is the report being written
(:class:`pipeline.report.build.Report`)."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from pipeline.report import learning_curves as LC
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import row_styles
from pipeline.report.paper_numbers import PaperValue
from pipeline.report.pooling import convergence, describe_runs, pooled
from pipeline.report.spec import Row
from pipeline.stats import fmt, mean_band

COLLISIONS = "collisions (mean ± s.d. [95% CI])"


def styles_of(rows: list[tuple[Row, list[Cell]]]) -> dict[str, dict]:
    """The rows' line colours and styles by label (:func:`~pipeline.report.names.row_styles`):
    the same row looks the same in every figure."""
    found = row_styles([cells for _, cells in rows])
    return {row.label: style for (row, _), style in zip(rows, found)}


def safe(name: str) -> str:
    """A maze name (or a layout file's name) as part of a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def file_name(exp: Experiment, part: str, maze: str | None) -> str:
    """``<folder>_<part>``, and ``_<maze>`` for one maze of several."""
    return f"{exp.folder}_{part}{'' if maze is None else '_' + safe(maze)}"


def section_data(rep, exp: Experiment, data: pd.DataFrame, none: str) -> bool:
    """A per-cell section's data as ``tables/<folder>_data.csv``; without any, the sentence
    ``none`` instead. Whether there was data (the section goes on)."""
    if data.empty:
        rep.add(none)
        return False
    rep.data(f"{exp.folder}_data", data)
    return True


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
    rep, exp: Experiment, rows: list[tuple[Row, list[Cell]]], maze: str | None = None
) -> list[pd.DataFrame]:
    """Learning curves of ``rows``: collisions per episode, mean over run seeds with a 95% band;
    returns their data (:func:`write_curves_table`)."""
    series = [
        (row, a) for row, cells in rows if (a := pooled(cells, Cell.collisions_by_episode)).size
    ]
    if not series:
        return []
    table = []
    styles = styles_of(rows)
    mazes = {row.label: " / ".join(sorted({c.maze for c in cells})) for row, cells in rows}
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
                    "colour": styles[row.label]["color"],  # the DVC plots' colour (one palette)
                    "maze": mazes[row.label],  # the DVC plots' panel
                    "episode": np.arange(mean.size),
                    "mean": mean,
                    "ci_low": lo,
                    "ci_high": hi,
                }
            )
        )
    where = "" if maze is None else f", {maze}"
    name = file_name(exp, "learning_curves", maze) + ".png"
    n_runs = sorted({a.shape[0] for _, a in series})
    scales = LC.curves(
        {row.label: a for row, a in series},
        f"Collisions per episode{where}: mean over runs, 95% band",
        rep.out / "figures" / name,
        styles=styles,
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
    return table


def write_curves_table(
    rep, exp: Experiment, frames: list[pd.DataFrame], maze: str | None = None
) -> None:
    """``tables/<folder>_learning_curves.csv`` (``_<maze>`` for one maze of several: a DVC plot
    each, whose series have distinct colours); long format, a row per series and episode."""
    if frames:
        frame = pd.concat(frames, ignore_index=True)
        rep.data(file_name(exp, "learning_curves", maze), frame, float_format="%.6g")


def support_part(
    rep, exp: Experiment, rows: list[tuple[Row, list[Cell]]], maze: str | None = None
) -> None:
    """The query accuracy of the rows' support sets over the run (rows with a recogniser)."""
    series = {row.label: pooled(cells, Cell.support_accuracy) for row, cells in rows}
    series = {k: a for k, a in series.items() if a.size}
    if not series:
        return
    where = "" if maze is None else f", {maze}"
    name = file_name(exp, "support_accuracy", maze) + ".png"
    title = f"Query accuracy of the run's support set over the run{where}"
    scales = LC.curves(
        series,
        title,
        rep.out / "figures" / name,
        ylabel="query accuracy of the support set",
        styles=styles_of(rows),
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
