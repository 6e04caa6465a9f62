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

The claims that compare few-shot settings on the 5x5 (:data:`CLAIMS`: 9, Figure 8; 11, Figure 9;
12, Figure 10) are decided per network and over the five: for each check, the collisions per run
of the setting that should collide more minus those of the one that should collide fewer, paired
on the run seeds (SSRL, which has no network, is paired with every network), with the claims
section's rule (holds when the 95% interval lies above zero, does not hold when below, not
resolved otherwise); a claim of several checks holds when each holds. Beside each network: the
query pictures it names right with the original support set, read from its static cells'
recognitions (each picture the robot met, its prediction: the same in every run), against the
break-even accuracy of the ``accuracy_curve`` experiment (few-shot against SSRL on the 5x5, with
its interval).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.report.accuracy_curve import break_even_table, split
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.formats import combined, estimate, interval, verdict
from pipeline.report.names import recogniser_name, recogniser_of
from pipeline.report.parts import section_data
from pipeline.stats import bootstrap_means, cluster_ratio_draws, percentile_ci
from pipeline.world.pictures import picture_category

RESAMPLES, SEED = 2000, 0
#: A network's seed, from its checkpoint file (``relation_net.pt``: 0; ``..._seed3.pt``: 3).
SEED_IN_NAME = re.compile(r"_seed(\d+)\.pt$")
#: The maze of the claims decided per network (Figures 8-10 are the paper's 5x5).
CLAIM_MAZE = "5x5"


@dataclass(frozen=True)
class NetworkClaim:
    """A claim of the claims section decided per network: ``more`` (a :func:`setting_of` label)
    collides more than each of ``fewer`` (one check each); ``after_first``: over the runs after
    the first (a carried-over support set starts as the original in the first)."""

    number: int
    source: str
    says: str
    more: str
    fewer: tuple[str, ...]
    after_first: bool = False


CLAIMS = (
    NetworkClaim(
        9,
        "Figure 8",
        "the performance of SSRL is slightly better than few-shot reasoning",
        "fewshot",
        ("ssrl",),
    ),
    NetworkClaim(
        11,
        "Figure 9",
        "[all the different substitution ways] can further reduce the collision number than "
        "few-shot reasoning with no substitution",
        "fewshot",
        tuple(f"fewshot_dss way {way}" for way in (1, 2, 3, 4)),
    ),
    NetworkClaim(
        12,
        "Figure 10",
        "the collision number can be reduced to a very low level if we do not restore the "
        "support set",
        "fewshot_dss way 1",
        ("fewshot_dss way 1 carry",),
        after_first=True,
    ),
)


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
        (table["maze"] == CLAIM_MAZE)
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
                "95% CI, runs resampled": interval(*over_runs),
                "95% CI, networks then runs": interval(*percentile_ci(both)),
            }
        )
    return rows


def claim_rows(runs: pd.DataFrame, claim: NetworkClaim, named: dict | None = None) -> list[dict]:
    """``claim`` per network and over the networks of each recogniser (module docstring), with the
    pictures each network names right (``named``: :func:`pictures_named`); no rows without
    records of both sides."""
    runs = runs[runs["maze"] == CLAIM_MAZE]
    if claim.after_first:
        runs = runs[runs["run"] > runs["run"].min()]
    rows = []
    for label, g in runs[runs["network"] >= 0].groupby("recogniser", sort=False):
        no_network = runs[runs["network"] < 0]
        diffs = [paired(pd.concat([g, no_network]), claim.more, fewer) for fewer in claim.fewer]
        if any(d.empty for d in diffs):
            continue
        for network in sorted(diffs[0]["network"].unique()):
            checks = [d[d["network"] == network]["d"] for d in diffs]
            intervals = [percentile_ci(bootstrap_means(c, seed=SEED)) for c in checks]
            right, met = (named or {}).get((label, network), (0, 0))
            pictures = f"{right}/{met}" if met else ""
            rows.append(claim_row(label, f"seed {network}", claim, checks, intervals, pictures))
        intervals = [
            percentile_ci(
                cluster_ratio_draws(d["d"], np.ones(len(d)), d["network"], within=True, seed=SEED)
            )
            for d in diffs
        ]
        n = diffs[0]["network"].nunique()
        over = f"the {n} network{'s' if n > 1 else ''} (networks, then runs)"
        rows.append(claim_row(label, over, claim, [d["d"] for d in diffs], intervals))
    return rows


def paired(runs: pd.DataFrame, more: str, fewer: str) -> pd.DataFrame:
    """Per network and run: ``more``'s collisions minus ``fewer``'s (column ``d``), paired on the
    run seeds; a side without a network (SSRL) is paired with every network of the other."""
    networks = sorted(runs.loc[runs["network"] >= 0, "network"].unique())

    def side(method: str) -> pd.DataFrame:
        rows = runs[runs["method"] == method][["network", "run", "collisions"]]
        if rows.empty or (rows["network"] >= 0).any():
            return rows
        return pd.concat([rows.assign(network=n) for n in networks])

    both = side(more).merge(side(fewer), on=["network", "run"], suffixes=("_more", "_fewer"))
    d = both["collisions_more"] - both["collisions_fewer"]
    return pd.DataFrame({"network": both["network"], "d": d})


def claim_row(
    label: str, network: str, claim: NetworkClaim, checks, intervals, pictures: str = ""
) -> dict:
    """One row for ``network``: each check's difference and interval, the claim's verdict and the
    query pictures the network names right (``pictures``)."""
    differences = "; ".join(estimate(c.mean(), *ci) for c, ci in zip(checks, intervals))
    return {
        "recogniser": label,
        "claim": claim.number,
        "network": network,
        "checks": ", ".join(f"{claim.more} − {f}" for f in claim.fewer),
        f"difference, {CLAIM_MAZE} [95% CI]": differences,
        "verdict": combined([verdict(lo, hi) for lo, hi in intervals]),
        "query pictures right": pictures,
    }


def networks_section(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The section (module docstring)."""
    runs = run_table(exp)
    if not section_data(rep, exp, runs, "No cell of this experiment is recorded.\n"):
        return
    rep.table(
        exp.folder,
        pd.DataFrame(spread_rows(runs)),
        "Collisions per run of each network (its mean over 100 runs), their mean, the spread across "
        "networks (s.d. of the networks' means) beside the spread across runs (s.d. within a "
        "network, averaged), and two 95% intervals of the mean: resampling runs only (these "
        "networks), and resampling networks, then each one's runs (a new draw of networks; "
        f"{RESAMPLES} resamples, seed {SEED}). Data: `tables/{exp.folder}_data.csv`.",
    )
    named = pictures_named(exp)
    found = {claim: claim_rows(runs, claim, named) for claim in CLAIMS}
    found = {claim: rows for claim, rows in found.items() if rows}
    if not found:
        return
    counts = []
    for claim, rows in found.items():
        table = pd.DataFrame(rows)
        per_network = table[table["network"].str.startswith("seed ")]
        held = "; ".join(
            f"{label} {(g['verdict'] == 'holds').sum()} of {len(g)}"
            for label, g in per_network.groupby("recogniser", sort=False)
        )
        counts.append(f"claim {claim.number} ({claim.source}) holds for {held} networks")
    even = break_even_5x5(experiments)
    beside = (
        f" The break-even accuracy of few-shot against SSRL on the 5x5 is {even} (the "
        "accuracy_curve section): a network naming that share of the pictures or more need not "
        "collide more than SSRL (claim 9)."
        if even
        else ""
    )
    rep.add(
        f"**The claims per network.** {'; '.join(counts)}. A network's verdict is a property of "
        "that network (its recognition of these query pictures), the verdict over the networks "
        f"one of the recipe.{beside}\n"
    )
    rep.table(
        f"{exp.folder}_claims",
        pd.DataFrame([row for rows in found.values() for row in rows]),
        "The claims comparing few-shot settings, per network and over the networks ("
        + "; ".join(f'{c.number}: "{c.says}"' for c in found)
        + "): per check, collisions per run of the first setting minus the second on the 5x5, "
        "paired on the run seeds (claim 12: the runs after the first); a claim holds when every "
        "check's 95% interval lies above zero, does not hold when one lies below.",
    )
