"""The ``generalisation`` section kind: do the paper's claims (section 4.2.2, Figure 8, Table 3)
hold beyond its three mazes? (``conf/experiment/generalisation.yaml``, issue 14.)

The experiment runs every method on many generated layouts of each of the paper's sizes
(``experiment.layouts``: :mod:`pipeline.world.layout_sets`). The records say what each cell ran:
its maze is the layout's spec (``random:7x7:16:3:unique``), which gives the size, and its records
keep the layout's rows, from which the layout features are computed
(:mod:`pipeline.report.layout_cells`). Per size: collisions over layouts per method; for each claim
the fraction of layouts where it holds by the claims section's verdict rule (the layouts are
independent draws of the generator: Wilson intervals); the DSS gain and whether it grows with the
size (a between-size claim, so no per-layout fraction); collisions against layout features.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from pipeline.report import figures_beyond as FB
from pipeline.report.checks import Claim, Data, checked
from pipeline.report.claims import FEWER_THAN_CONSTRAINED, FIGURE_8, TABLE3_READINGS, Fewer
from pipeline.report.experiments import Experiment
from pipeline.report.formats import estimate, share, verdict
from pipeline.report.layout_cells import (
    FEATURES,
    LayoutCells,
    by_size,
    colours,
    data_frame,
    feature_rows,
    fit,
    label,
    methods_of,
)
from pipeline.stats import bootstrap_ci, bootstrap_difference, wilson_ci

#: The paper's claims that one layout can check (:mod:`pipeline.report.claims` words the ones it
#: checks on every maze of Table 3 for a layout of one).
CLAIMS = (
    *FIGURE_8,
    Fewer(
        "Figure 8",
        "few-shot reasoning with the dynamic support set collides less than SSRL",
        (("ssrl", "fewshot_dss"),),
        quoted=False,
    ),
    Fewer("Table 3", "Sarsa has more collisions than Q-learning", (("sarsa", "qlearning"),)),
    FEWER_THAN_CONSTRAINED,
    *(replace(claim, says=claim.says.replace(" on every maze", "")) for claim in TABLE3_READINGS),
)


#: The claims' view of the records for a layout's checks: the paper prints no numbers for
#: generated layouts, so no experiment to look them up in.
NO_PAPER = Data([])


#: What is counted over a size's layouts for each claim: the table's column, the CSV's outcome.
OUTCOMES = (
    ("holds", "holds"),
    ("does not hold", "does_not_hold"),
    ("means in the claimed order", "means_ordered"),
)


def claim_rows(sizes: dict[str, list[LayoutCells]]) -> tuple[list[dict], list[dict]]:
    """Per size and claim: the layouts where it holds, does not hold, and where the means are in
    the claimed order (table rows and their CSV form)."""
    table, data = [], []
    for size, layouts in sizes.items():
        for claim in CLAIMS:
            verdicts, means_ok = [], []
            for lay in layouts:
                c: Claim = checked(
                    claim.source,
                    claim.says,
                    lambda claim=claim, lay=lay: claim.checks(NO_PAPER, lay.arm),
                    quoted=claim.quoted,
                )
                if c.verdict == "not checked":
                    continue
                verdicts.append(c.verdict)
                means_ok.append(all(k.estimate > 0 for k in c.checks))
            n = len(verdicts)
            if not n:
                continue
            counts = (verdicts.count("holds"), verdicts.count("does not hold"), sum(means_ok))
            text = c.text()
            table.append(
                {"size": size, "where": claim.source, "the paper": text, "layouts": n}
                | {column: share(k, n, 0) for (column, _), k in zip(OUTCOMES, counts)}
            )
            for (_, what), k in zip(OUTCOMES, counts):
                low, high = wilson_ci(k / n, n)
                data.append(
                    {
                        "size": size,
                        "source": claim.source,
                        "claim": text,
                        "outcome": what,
                        "layouts": n,
                        "count": k,
                        "fraction": k / n,
                        "ci_low": low,
                        "ci_high": high,
                    }
                )
    return table, data


def gains(sizes: dict[str, list[LayoutCells]]) -> tuple[list[dict], dict[str, np.ndarray]]:
    """Per size the DSS gain (few-shot without minus with the dynamic support set) of each layout:
    a table row (mean over layouts [95% bootstrap CI], relative gain) and the per-layout gains."""
    rows, per_size = [], {}
    for size, layouts in sizes.items():
        ok = [lay for lay in layouts if {"fewshot", "fewshot_dss"} <= set(lay.cells)]
        if not ok:
            continue
        g = np.array([lay.mean("fewshot") - lay.mean("fewshot_dss") for lay in ok])
        without = np.array([lay.mean("fewshot") for lay in ok])
        per_size[size] = g
        rows.append(
            {
                "size": size,
                "layouts": len(ok),
                "few-shot without DSS (mean)": f"{without.mean():.2f}",
                "DSS gain (mean [95% CI])": estimate(g.mean(), *bootstrap_ci(g)),
                "relative gain": f"{100 * g.mean() / without.mean():.1f}%"
                if without.mean()
                else "",
                "layouts with a gain": share(int((g > 0).sum()), len(ok), 0),
            }
        )
    return rows, per_size


def growth(per_size: dict[str, np.ndarray]) -> list[dict]:
    """The DSS gain grows with the size: the difference of consecutive sizes' mean gains with a
    95% bootstrap interval over layouts (unpaired) and its verdict."""
    out = []
    names = list(per_size)
    for small, large in zip(names, names[1:]):
        est, low, high = bootstrap_difference(per_size[large], per_size[small], paired=False)
        out.append(
            {
                "check": f"DSS gain on {large} − on {small}",
                "estimate [95% CI]": estimate(est, low, high),
                "verdict": verdict(low, high),
                "estimate": est,
                "ci_low": low,
                "ci_high": high,
            }
        )
    return out


def generalisation_section(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The section (module docstring); the other ``experiments`` are not used."""
    sizes, notes = by_size(exp)
    if not sizes:
        rep.add("No cell of this experiment is on a generated layout.\n")
        return
    runs = sorted({len(c.runs()) for c in exp.cells.values()})
    counts = ", ".join(f"{len(v)} on {s}" for s, v in sizes.items())
    rep.add(
        "Every method on generated layouts of the paper's sizes and obstacle counts (layouts of the paper's "
        "kind: a single shortest path lined by obstacles; `pipeline/world/generate.py`), "
        f"{'/'.join(map(str, runs))} runs per cell; layouts: {counts}. A claim is checked on each layout as "
        "the claims section checks it on the paper's mazes (95% bootstrap interval over the layout's run seeds, "
        "paired); the fractions are over layouts, with 95% Wilson intervals."
        + "".join(f"\n\nNote: {n}." for n in notes)
        + "\n"
    )
    df = data_frame(sizes)
    rep.data(f"{exp.folder}_data", df, float_format="%.6g")
    name = f"{exp.folder}.png"
    FB.layout_boxes(
        {
            s: {
                label(lays, m): df[(df["size"] == s) & (df["method"] == m)][
                    "collisions_mean"
                ].to_numpy()
                for m in methods_of(lays)
            }
            for s, lays in sizes.items()
        },
        rep.out / "figures" / name,
        {
            label(lays, m): c
            for lays in sizes.values()
            for m, c in colours(sizes).items()
            if m in lays[0].cells
        },
    )
    rep.figure(
        f"figures/{name}",
        "Mean collisions per run on each generated layout, one box per method and size "
        "(median, quartiles, whiskers to 1.5 IQR, layouts beyond as points; log scale). "
        f"Data: `tables/{exp.folder}_data.csv`.",
    )
    table, data = claim_rows(sizes)
    rep.data(f"{exp.folder}_claims", pd.DataFrame(data), float_format="%.6g")
    rep.table(
        exp.folder,
        pd.DataFrame(table),
        "The paper's claims on each generated layout: the layouts where the claim holds (every check on the "
        "claimed side by the claims section's verdict rule, Holm's correction within the claim), where it "
        "does not hold (one on the other side; the rest are not resolved) and where the layout's mean collisions lie in the claimed order; fraction of layouts with "
        f"its 95% Wilson interval. Counts per claim and outcome: `tables/{exp.folder}_claims.csv`.",
    )
    gain_rows, per_size = gains(sizes)
    if gain_rows:
        grow = growth(per_size)
        rep.table(
            f"{exp.folder}_dss_gain",
            pd.DataFrame(gain_rows),
            "The dynamic support set's gain (few-shot without minus with it, mean collisions per run) per size: "
            "mean over layouts with its 95% bootstrap interval over layouts (2000 resamples, seed 0).",
        )
        if grow:
            rep.table(
                f"{exp.folder}_dss_growth",
                pd.DataFrame(grow)[["check", "estimate [95% CI]", "verdict"]],
                'Table 3\'s reading "the gain of the dynamic support set grows with the maze" over layouts: '
                "the difference of two sizes' mean gains, 95% bootstrap interval over layouts (unpaired).",
            )
    name = f"{exp.folder}_features.png"
    FB.feature_scatter(df, FEATURES, rep.out / "figures" / name, fit, colours(sizes))
    rep.figure(
        f"figures/{name}",
        "Mean collisions per run on each layout against its features, one colour per "
        "method, with its least-squares line (none where the feature is constant over a "
        "size's layouts); log scale.",
    )
    rep.table(
        f"{exp.folder}_features",
        pd.DataFrame(feature_rows(df)),
        "Collisions against layout features: slope of the least-squares line of mean collisions per run over "
        "the layouts of a size, with its 95% t interval, and the correlation r.",
    )
