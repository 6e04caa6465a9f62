"""How many substitutions each category of the dynamic support set sees in a run (paper section
3.3), counted from the records (one ``Substitutions`` row per support-set change; a run's start is a
row of -1s), and what that allows: two substitution ways can give different outcomes only in a
run where some category takes more substitutions than they agree on
(:func:`~pipeline.fewshot.support_set.ways_agree_until`), e.g. ways 3 and 4 only past the K = 5
original shots of a category. The report's claims mark a comparison of ways that no run lets
differ as not testable (:func:`cannot_differ`) and show the counts (:func:`substitution_part`)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.fewshot.paper_tables import K_SHOT, N_WAY
from pipeline.fewshot.support_set import ways_agree_until
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import (
    PAPER_RECOGNISER,
    recogniser_declarations,
    recogniser_name,
    recogniser_of,
    recogniser_reads,
)


def substitution_counts(substitutions: pd.DataFrame, runs, n_way: int = N_WAY) -> np.ndarray:
    """(runs, categories): substitutions of each category in each of ``runs`` (the rows of
    ``substitutions`` with a picture, i.e. not a run's starting row)."""
    real = substitutions[substitutions["picture"] >= 0]
    counts = real.groupby(["run", "category"]).size().unstack(fill_value=0)
    return counts.reindex(index=list(runs), columns=range(n_way), fill_value=0).to_numpy(int)


def count_summary(counts: np.ndarray, k_shot: int = K_SHOT) -> dict:
    """The mean and the largest number of substitutions a category takes in a run, and the share of
    runs in which some category takes more than ``k_shot`` (all its original shots replaced: where
    ways 3 and 4 can differ at all)."""
    counts = np.asarray(counts)
    return {
        "runs": len(counts),
        "mean": float(counts.mean()) if counts.size else 0.0,
        "max": int(counts.max()) if counts.size else 0,
        "past_k": float((counts.max(axis=1) > k_shot).mean()) if counts.size else 0.0,
    }


def support_states(substitutions: pd.DataFrame, reads: str) -> dict[int, list[tuple]]:
    """Per run, its support set after each substitution as a recogniser that ``reads`` it sees it
    (:data:`~pipeline.fewshot.support_set.SUPPORT_READS`): the picture at every substituted
    (category, position), only the substituted pictures each category holds, or none at all
    (``nothing``: no way changes what such a recogniser sees)."""
    if reads == "nothing":
        return {}
    real = substitutions[substitutions["picture"] >= 0]
    real = real.sort_values(["run", "episode", "step"], kind="stable")
    out = {}
    for run, g in real.groupby("run"):
        held, states = {}, []
        for c, pos, picture in zip(g["category"], g["position"], g["picture"]):
            held[int(c), int(pos)] = int(picture)
            if reads == "positions":
                states.append(tuple(sorted(held.items())))
            else:
                states.append(tuple(sorted((c, p) for (c, _), p in held.items())))
        out[int(run)] = states
    return out


def support_differs(a: pd.DataFrame, b: pd.DataFrame, runs, reads: str) -> np.ndarray:
    """Per run of ``runs``: whether the support sets the substitutions ``a`` and ``b`` (of two
    cells, e.g. two ways) built came to differ, as a recogniser that ``reads`` them sees them."""
    first, second = support_states(a, reads), support_states(b, reads)
    return np.array([first.get(r, []) != second.get(r, []) for r in runs], dtype=bool)


def cell_counts(cell: Cell) -> np.ndarray | None:
    """The cell's :func:`substitution_counts`; None where its records hold no substitution rows
    (nothing tells how its support set changed)."""
    subs = cell.substitutions
    if subs is None or "picture" not in subs or len(subs) == 0:
        return None
    return substitution_counts(subs, cell.runs())


def cannot_differ(cells: list[Cell], a: int, b: int, recogniser: str | None) -> str:
    """Why ways ``a`` and ``b`` (0: the static support set) cannot change anything in any run of
    ``cells`` (the cells compared) with ``recogniser`` (its ``reads_support``), or "" when they
    can (or the records do not tell): every run's categories take no more substitutions than the
    two ways agree on."""
    reads = recogniser_reads(recogniser) if recogniser else "positions"
    agree = ways_agree_until(a, b, K_SHOT, reads)
    what = f"the static support set and way {b}" if a == 0 else f"ways {a} and {b}"
    name = recogniser_name(recogniser) if recogniser else "a recogniser"
    held = {
        "positions": "place the same pictures at the same positions",
        "substituted": f"hold the same substituted pictures in each category (all the {name} "
        "reads of it)",
        "nothing": f"change nothing the {name} reads (it has no support positions)",
    }[reads]
    if agree is None:
        return f"{what} always {held}"
    counts = [cell_counts(c) for c in cells]
    if any(c is None for c in counts):
        return ""
    most = max(int(c.max()) if c.size else 0 for c in counts)
    if most > agree:
        return ""
    return (
        f"{what} {held} while no category takes more than {agree} substitution"
        f"{'s' if agree != 1 else ''} in a run, and in none of the {len(counts[0])} runs of "
        f"{'each' if len(counts) > 1 else 'the way'} does one take more than {most}"
    )


def way_cells(experiments: list[Experiment]) -> list[Cell]:
    """The cells of the dynamic support set in experiments that record more than one way (those
    whose claims and tables compare the ways)."""
    out = []
    for e in experiments:
        dss = [c for c in e.cells.values() if c.info["method"].get("dynamic_support")]
        if len({c.info.get("substitution") for c in dss}) > 1:
            out += dss
    return out


def substitution_table(experiments: list[Experiment]) -> pd.DataFrame:
    """One row per cell of :func:`way_cells` with records of substitutions: its experiment, maze,
    recogniser, way, :func:`count_summary` and the share of runs whose support set came to differ
    from that of the lowest way of its experiment, maze and recogniser (:func:`support_differs`)."""
    groups: dict[tuple, list[Cell]] = {}
    for cell in way_cells(experiments):
        if cell_counts(cell) is not None:
            key = (cell.experiment, cell.maze, recogniser_of(cell.info, cell.config))
            groups.setdefault(key, []).append(cell)
    rows = []
    for (experiment, maze, recogniser), cells in groups.items():
        cells = sorted(cells, key=lambda c: int(c.info.get("substitution")))
        reads = recogniser_reads(recogniser) if recogniser else "positions"
        for cell in cells:
            differs = support_differs(
                cell.substitutions, cells[0].substitutions, cell.runs(), reads
            )
            rows.append(
                {
                    "experiment": experiment,
                    "maze": maze,
                    "recogniser": recogniser,
                    "way": int(cell.info.get("substitution")),
                    **count_summary(cell_counts(cell)),
                    "compared_with_way": int(cells[0].info.get("substitution")),
                    "support_differs": float(differs.mean()),
                }
            )
    return pd.DataFrame(rows)


def substitution_part(rep, experiments: list[Experiment]) -> None:
    """The claims section's paragraph and table of substitutions per category and run (the ways
    side by side, one row per experiment, maze and recogniser) and ``tables/substitutions.csv``."""
    table = substitution_table(experiments)
    if table.empty:
        return
    readers = {
        reads: ", ".join(d.display for d in recogniser_declarations() if d.reads == reads) or "none"
        for reads in ("substituted", "nothing")
    }
    rep.data("substitutions", table, float_format="%.6g")
    wide = []
    table = table.assign(
        other=table["recogniser"] != PAPER_RECOGNISER,  # the paper's recogniser first
        side=table["maze"].str.split("x").str[0].astype(int),  # mazes by size, not by name
    ).sort_values(["experiment", "other", "recogniser", "side"], kind="stable")
    for (exp, maze, rec), g in table.groupby(["experiment", "maze", "recogniser"], sort=False):
        g = g.sort_values("way")
        wide.append(
            {
                "experiment": exp,
                "maze": maze,
                "recogniser": recogniser_name(rec),
                "ways": " / ".join(map(str, g["way"])),
                "mean": " / ".join(f"{m:.2f}" for m in g["mean"]),
                "max": " / ".join(map(str, g["max"])),
                f"runs with a category past K = {K_SHOT}": " / ".join(
                    f"{100 * s:.0f}%" for s in g["past_k"]
                ),
                "runs whose support set differs from the first way's": " / ".join(
                    f"{100 * s:.0f}%" for s in g["support_differs"]
                ),
            }
        )
    rep.add(
        "**Where the substitution ways can differ.** A collision substitutes the picture into its "
        f"category's K = {K_SHOT} shots (section 3.3). Ways 3 and 4 choose the same positions from "
        "the same random stream until a category's first round of K is over, so they can give "
        f"different outcomes only in a run where some category takes more than {K_SHOT} "
        f"substitutions (from its 6th on). A recogniser that reads only which substituted pictures "
        f"a category holds ({readers['substituted']}) cannot tell ways 1 and 4 apart at all (both "
        "replace the oldest substituted picture once the originals are out), ways 1 and 3 only "
        "past K substitutions, and way 2 from the others from a category's 2nd on; a recogniser "
        f"without support positions ({readers['nothing']}) none of the ways; any other is taken "
        "to read the shot at every position. A check comparing ways "
        "that no recorded run lets differ is **not testable with this recogniser**, says why, and "
        "leaves the claim's other checks to decide it (it has no place in Holm's correction); a "
        "claim with only such checks is not testable. Substitutions a category takes in a run "
        "(mean over categories and runs, the largest, and the share of runs where some category "
        "takes more than K), and the share of runs whose support set came to differ from the "
        "first way's (as the recogniser reads it: the picture at every position, or the "
        "substituted pictures held), ways in the order given; data: `tables/substitutions.csv`.\n\n"
        + pd.DataFrame(wide).to_markdown(index=False)
        + "\n"
    )
