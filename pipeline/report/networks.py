"""The ``networks`` section kind: is a few-shot collision figure a property of the method or of
one trained network? (``conf/experiment/networks.yaml``, issue 42.)

Five networks of each kind (the same recipe, seeds 0-4) each run few-shot reasoning without and
with the DSS on the paper's mazes, and on the 5x5 the DSS's four substitution ways (Figure 9) and
the support set carried over (Figure 10). Per recogniser kind, method and maze the section sets the
spread across networks (the standard deviation of the five networks' mean collisions per run)
beside the spread across runs (within a network, averaged over the five), and gives two 95%
intervals of the mean over networks: one that resamples runs only (for these five networks) and
one that resamples networks, then each drawn network's runs (for a new draw of networks; the
two-level bootstrap of :func:`pipeline.stats.cluster_ratio_draws`).

Claim 9 ("the performance of SSRL is slightly better than few-shot reasoning", Figure 8, 5x5) is
decided per network and over the five: few-shot's collisions per run minus SSRL's, paired on the
run seeds, with the claims section's rule (holds when the 95% interval lies above zero, does not
hold when below, not resolved otherwise). Beside each network: the query pictures it names right
with the original support set, read from its static cells' recognitions (each picture the robot
met, its prediction: the same in every run), against the break-even accuracy of the
``accuracy_curve`` experiment (few-shot against SSRL on the 5x5, with its interval).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from pipeline.report.accuracy_curve import break_even_table, split
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import recogniser_name, recogniser_of
from pipeline.stats import bootstrap_means, cluster_ratio_draws, percentile_ci
from pipeline.world.pictures import picture_category

RESAMPLES, SEED = 2000, 0
#: A network's seed, from its checkpoint file (``relation_net.pt``: 0; ``..._seed3.pt``: 3).
SEED_IN_NAME = re.compile(r"_seed(\d+)\.pt$")
#: Claim 9's maze and methods (Figure 8).
CLAIM9 = ("5x5", "fewshot", "ssrl")


def network_of(cell: Cell) -> int | None:
    """The seed of the network a cell ran (None: no network), from its recorded checkpoint."""
    checkpoint = ((cell.info.get("recogniser") or {}).get("checkpoint") or {}).get("path")
    if not checkpoint:
        return None
    found = SEED_IN_NAME.search(str(checkpoint))
    return int(found[1]) if found else 0


def pictures_named(exp: Experiment) -> dict[tuple[str, int], tuple[int, int]]:
    """(recogniser, network) -> (pictures named right, pictures met) over the network's cells with
    the original support set (few-shot without the DSS): a static support set names a picture the
    same way in every run."""
    seen: dict[tuple[str, int], dict[int, int]] = {}
    for cell in exp.cells.values():
        kind = recogniser_of(cell.info, cell.config)
        if not kind or cell.info["method"].get("dynamic_support") or cell.recognitions.empty:
            continue
        named = seen.setdefault((recogniser_name(kind), network_of(cell)), {})
        pairs = cell.recognitions[["picture", "predicted"]].drop_duplicates()
        named.update(zip(pairs["picture"].astype(int), pairs["predicted"].astype(int)))
    return {
        key: (sum(picture_category(p) == c for p, c in named.items()), len(named))
        for key, named in seen.items()
    }


def break_even_5x5(experiments: list[Experiment]) -> str | None:
    """The accuracy_curve experiment's break-even accuracy of few-shot (static support set)
    against SSRL on the 5x5, as its table prints it (``0.5 [0.5, 0.5]``), or None."""
    found = next((e for e in experiments if e.spec.kind == "accuracy_curve"), None)
    if found is None:
        return None
    table = break_even_table(split(found))
    row = table[
        (table["maze"] == CLAIM9[0])
        & (table["against"] == "SSRL")
        & table["method"].str.contains("static")
    ]
    return None if row.empty else f"{row['break-even p'].iloc[0]} {row['95% CI'].iloc[0]}"


def setting_of(cell: Cell) -> str:
    """The cell's method, with its substitution way and support mode where the method has a
    dynamic support set (``fewshot_dss way 2``, ``fewshot_dss way 1 carry``; Figures 9 and 10)."""
    if not cell.info["method"].get("dynamic_support"):
        return cell.method
    carry = " carry" if cell.info.get("support") == "carry" else ""
    return f"{cell.method} way {cell.info.get('substitution')}{carry}"


def run_table(exp: Experiment) -> pd.DataFrame:
    """One row per run of every cell: recogniser (display name; none for SSRL), network seed,
    method (:func:`setting_of`), maze, run and collisions."""
    frames = []
    for cell in exp.cells.values():
        kind = recogniser_of(cell.info, cell.config)
        frames.append(
            pd.DataFrame(
                {
                    "recogniser": recogniser_name(kind) if kind else "",
                    "network": network_of(cell) if kind else -1,
                    "method": setting_of(cell),
                    "maze": cell.maze,
                    "run": cell.runs(),
                    "collisions": cell.collisions_per_run(),
                }
            )
        )
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def maze_cells(maze: str) -> int:
    """A maze's cell count from its ``<W>x<H>`` (``5x5``: 25; ``random:7x7:...``: 49), its order
    in the tables; 0 for a layout file."""
    found = re.search(r"(\d+)x(\d+)", maze)
    return int(found[1]) * int(found[2]) if found else 0


def verdict(lo: float, hi: float) -> str:
    """The claims section's rule for one check at the 95% level."""
    return "holds" if lo > 0 else "does not hold" if hi < 0 else "not resolved"


def spread_rows(runs: pd.DataFrame) -> list[dict]:
    """Per recogniser, method and maze: each network's mean, the spreads and the two intervals
    (module docstring)."""
    rows = []
    picked = runs[runs["network"] >= 0]
    keys = ["recogniser", "method", "cells", "maze"]  # two mazes of one size stay apart
    picked = picked.assign(cells=picked["maze"].map(maze_cells)).sort_values(keys, kind="stable")
    for (label, method, _, maze), g in picked.groupby(keys, sort=False):
        by_net = g.groupby("network")["collisions"]
        means = by_net.mean()
        runs_only = [bootstrap_means(v, seed=SEED).reshape(1, -1) for _, v in by_net]
        over_runs = percentile_ci(np.concatenate(runs_only).mean(axis=0))
        both = cluster_ratio_draws(
            g["collisions"], np.ones(len(g)), g["network"], within=True, seed=SEED
        )
        lo, hi = percentile_ci(both)
        rows.append(
            {
                "recogniser": label,
                "method": method,
                "maze": maze,
                "networks": len(means),
                "each network (seed 0, 1, ...)": " / ".join(f"{m:.2f}" for m in means),
                "mean": f"{means.mean():.2f}",
                "s.d. across networks": f"{means.std(ddof=1):.2f}" if len(means) > 1 else "",
                "s.d. across runs": f"{by_net.std(ddof=1).mean():.2f}",
                "95% CI, runs resampled": f"[{over_runs[0]:.2f}, {over_runs[1]:.2f}]",
                "95% CI, networks then runs": f"[{lo:.2f}, {hi:.2f}]",
            }
        )
    return rows


def claim9_rows(runs: pd.DataFrame, named: dict | None = None) -> list[dict]:
    """Claim 9 per network and over the networks of each recogniser (module docstring), with the
    pictures each network names right (``named``: :func:`pictures_named`)."""
    maze, fewshot, ssrl = CLAIM9
    base = runs[(runs["method"] == ssrl) & (runs["maze"] == maze)].set_index("run")["collisions"]
    if base.empty:
        return []
    rows = []
    cells = runs[(runs["method"] == fewshot) & (runs["maze"] == maze) & (runs["network"] >= 0)]
    for label, g in cells.groupby("recogniser", sort=False):
        diffs = g.assign(d=g["collisions"].to_numpy() - base.reindex(g["run"]).to_numpy())
        for network, n in diffs.groupby("network"):
            lo, hi = percentile_ci(bootstrap_means(n["d"], seed=SEED))
            right, met = (named or {}).get((label, network), (0, 0))
            row = claim9_row(label, f"seed {network}", n["d"].mean(), lo, hi)
            rows.append({**row, "query pictures right": f"{right}/{met}" if met else ""})
        draws = cluster_ratio_draws(
            diffs["d"], np.ones(len(diffs)), diffs["network"], within=True, seed=SEED
        )
        lo, hi = percentile_ci(draws)
        over = f"the {diffs['network'].nunique()} networks (networks, then runs)"
        rows.append(
            {**claim9_row(label, over, diffs["d"].mean(), lo, hi), "query pictures right": ""}
        )
    return rows


def claim9_row(label: str, network: str, mean: float, lo: float, hi: float) -> dict:
    return {
        "recogniser": label,
        "network": network,
        "few-shot − SSRL, 5x5 [95% CI]": f"{mean:.2f} [{lo:.2f}, {hi:.2f}]",
        "claim 9": verdict(lo, hi),
    }


def networks_section(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The section (module docstring)."""
    runs = run_table(exp)
    if runs.empty:
        rep.add("No cell of this experiment is recorded.\n")
        return
    rep.data(f"{exp.folder}_data", runs)
    rep.table(
        exp.folder,
        pd.DataFrame(spread_rows(runs)),
        "Collisions per run of each network (its mean over 100 runs), their mean, the spread across "
        "networks (s.d. of the networks' means) beside the spread across runs (s.d. within a "
        "network, averaged), and two 95% intervals of the mean: resampling runs only (these "
        "networks), and resampling networks, then each one's runs (a new draw of networks; "
        f"{RESAMPLES} resamples, seed {SEED}). Data: `tables/{exp.folder}_data.csv`.",
    )
    rows = claim9_rows(runs, pictures_named(exp))
    if rows:
        table = pd.DataFrame(rows)
        per_network = table[table["network"].str.startswith("seed ")]
        counts = "; ".join(
            f"{label}: holds for {(g['claim 9'] == 'holds').sum()} of {len(g)} networks"
            for label, g in per_network.groupby("recogniser", sort=False)
        )
        even = break_even_5x5(experiments)
        beside = (
            f" The break-even accuracy of few-shot against SSRL on the 5x5 is {even} (the "
            "accuracy_curve section): a network naming that share of the pictures or more need not "
            "collide more than SSRL."
            if even
            else ""
        )
        rep.add(
            f"**Claim 9 per network.** {counts}. A network's verdict is a property of that network "
            "(its recognition of these query pictures), the verdict over the networks one of the "
            f"recipe.{beside}\n"
        )
        rep.table(
            f"{exp.folder}_claim9",
            table,
            'Claim 9, "the performance of SSRL is slightly better than few-shot reasoning", per '
            "network and over the networks: few-shot's collisions per run minus SSRL's on the 5x5, "
            "paired on the run seeds; holds when the 95% interval lies above zero.",
        )
