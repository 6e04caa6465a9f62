"""The ``generalisation`` section kind: do the paper's claims (section 4.2.2, Figure 8, Table 3)
hold beyond its three mazes? (``conf/experiment/generalisation.yaml``, issue 14.)

The experiment runs every method on many generated layouts of each of the paper's sizes
(``experiment.layouts``: :mod:`pipeline.world.layout_sets`). The records say what each cell ran:
its maze is the layout's spec (``random:7x7:16:3:unique``), which gives the size, and its records
keep the layout's rows, from which the layout features are computed. Per size:

* ``figures/<folder>.png``: the distribution over layouts of mean collisions per run, one box per
  method (log scale).
* ``tables/<folder>.md|csv``: for each claim, the fraction of layouts where it **holds** (every
  check's 95% interval on the claimed side: the checks of :mod:`pipeline.report.claims`, bootstrap
  over the layout's run seeds, paired), where it **does not hold** and where the claimed order holds
  for the means alone, each with a 95% Wilson interval over layouts (the layouts are independent
  draws of the generator). Table 3's order is :func:`pipeline.report.claims.order_checks`.
* ``tables/<folder>_dss_gain.md|csv``: the gain of the dynamic support set (few-shot without minus
  with it) per size, mean over layouts with a 95% bootstrap interval over layouts, and whether it
  grows with the size (difference of the sizes' mean gains, bootstrap over layouts, unpaired: the
  sizes' layouts are unrelated). A between-size claim has no per-layout fraction.
* ``figures/<folder>_features.png`` and ``tables/<folder>_features.md|csv``: mean collisions per
  run against three layout features (:func:`features`), one least-squares line per method, its
  slope with a 95% t interval; a feature constant over a size's layouts (the shortest path of every
  ``unique`` layout is monotone: ``W+H-2`` moves) has no line.
* ``tables/<folder>_data.csv``: one row per cell: size, layout, method, collisions, features.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.report import figures as F
from pipeline.report.claims import Arm, Claim, Data, Missing, checked, fewer, order_checks
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import method_colour, method_name, method_order
from pipeline.report.stats import bootstrap_ci, bootstrap_difference, t_quantile_975, wilson_ci
from pipeline.world.generate import is_spec, parse_spec
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import bfs_distances, parse_layout

#: Layout features (:func:`features`) and their axis labels.
FEATURES = {
    "unsafe_pairs": "unsafe (state, action) pairs from reachable cells",
    "obstacles_reachable": "obstacles next to a reachable cell",
    "shortest_path": "shortest path (moves)",
}


@dataclass(frozen=True)
class LayoutClaim:
    """A claim checked on each layout: ``make(data, arm)`` gives its checks, where ``arm(method)``
    is the layout's :class:`~pipeline.report.claims.Arm` of a method."""

    source: str
    says: str
    make: object
    quoted: bool = True


def pairs(*more_less: tuple[str, str]):
    """Checks that the first method of each pair collides more than the second."""

    def make(data: Data, arm) -> list:
        return [fewer(data, f"{a} − {b}", arm(a), arm(b)) for a, b in more_less]

    return make


#: The paper's claims that one layout can check (claims.py words them the same way).
CLAIMS = (
    LayoutClaim(
        "Figure 8",
        "algorithms with the safety guarantee can significantly reduce the number of collisions "
        "than the algorithm without a safety guarantee",
        pairs(("qlearning", "shield"), ("qlearning", "ssrl"), ("qlearning", "fewshot")),
    ),
    LayoutClaim(
        "Figure 8",
        "SSRL and few-shot reasoning (without a dynamic support set) [...] both of them have a "
        "better performance in safety exploration than Q-learning with shield",
        pairs(("shield", "ssrl"), ("shield", "fewshot")),
    ),
    LayoutClaim(
        "Figure 8",
        "the performance of SSRL is slightly better than few-shot reasoning",
        pairs(("fewshot", "ssrl")),
    ),
    LayoutClaim(
        "Figure 8",
        "few-shot reasoning with the dynamic support set collides less than SSRL",
        pairs(("ssrl", "fewshot_dss")),
        quoted=False,
    ),
    LayoutClaim(
        "Table 3", "Sarsa has more collisions than Q-learning", pairs(("sarsa", "qlearning"))
    ),
    LayoutClaim(
        "Table 3",
        "our method, no matter with or without the dynamic support set, has fewer collisions "
        "than constrained RL methods",
        pairs(("constrained", "fewshot"), ("constrained", "fewshot_dss")),
    ),
    LayoutClaim(
        "Table 3",
        "collisions fall in the order of its rows: Sarsa, constrained RL, our method without, "
        "with the dynamic support set",
        lambda data, arm: order_checks(data, arm),
        quoted=False,
    ),
    LayoutClaim(
        "Table 3",
        "the dynamic support set reduces collisions",
        pairs(("fewshot", "fewshot_dss")),
        quoted=False,
    ),
)


# ------------------------------------------------------------------------------------ layouts
def features(rows: list[str]) -> dict[str, int]:
    """Features of a layout (its text rows): unsafe (state, action) pairs whose state the robot
    can reach (eq. 4's dangerous pairs it can meet), obstacles next to a reachable cell (the
    obstacles it can collide with) and the shortest start-goal path in moves."""
    layout = parse_layout("\n".join(rows), source="records")
    geometry = build_geometry(layout)
    blocked = np.zeros(layout.n_cells, dtype=np.bool_)
    blocked[list(layout.obstacles)] = True
    dist = bfs_distances(blocked, layout.height, layout.width, layout.start)
    reachable = dist >= 0
    hits = geometry.obstacle[reachable]
    return {
        "unsafe_pairs": int((hits >= 0).sum()),
        "obstacles_reachable": int(np.unique(hits[hits >= 0]).size),
        "shortest_path": int(dist[layout.goal]),
    }


@dataclass
class LayoutCells:
    """The cells run on one generated layout, by method (``conf/method/`` name)."""

    size: str
    maze: str
    seed: int
    rows: list[str]
    cells: dict[str, Cell] = field(default_factory=dict)
    _arms: dict[str, Arm] = field(default_factory=dict)

    def arm(self, method: str) -> Arm:
        """The method's collisions per run by run index (read once: 2,100 cells' frames add up)."""
        if method not in self._arms:
            if method not in self.cells:
                raise Missing(f"no records of {method} on {self.maze}")
            cell = self.cells[method]
            self._arms[method] = Arm(
                pd.Series(cell.collisions_per_run(), index=cell.runs()), [cell]
            )
        return self._arms[method]

    def mean(self, method: str) -> float:
        return float(self.arm(method).values.mean())


#: The claims' view of the records for a layout's checks: the paper prints no numbers for
#: generated layouts, so no experiment to look them up in.
NO_PAPER = Data([])


def by_size(exp: Experiment) -> tuple[dict[str, list[LayoutCells]], list[str]]:
    """The experiment's generated layouts grouped by size (sizes by their number of cells,
    layouts by seed), and notes on cells that are not on a generated layout."""
    found: dict[str, LayoutCells] = {}
    notes = []
    for cell in exp.cells.values():
        if not is_spec(cell.maze):
            notes.append(
                f"cell {cell.name} is not on a generated layout ({cell.maze}), so it is not shown"
            )
            continue
        spec = parse_spec(cell.maze)
        size = f"{spec.width}x{spec.height}"
        layout = found.setdefault(cell.maze, LayoutCells(size, cell.maze, spec.seed, cell.layout))
        layout.cells[cell.method] = cell
    sizes: dict[str, list[LayoutCells]] = {}
    for layout in sorted(found.values(), key=lambda lay: lay.seed):
        sizes.setdefault(layout.size, []).append(layout)
    order = sorted(sizes, key=lambda s: (np.prod([int(x) for x in s.split("x")]), s))
    return {s: sizes[s] for s in order}, notes


def methods_of(layouts: list[LayoutCells]) -> list[str]:
    """The methods every layout of a size has, in their declared order (``METHODS`` of
    :mod:`pipeline.rl.rules`; undeclared methods after, by name)."""
    common = set.intersection(*(set(lay.cells) for lay in layouts)) if layouts else set()
    return sorted(common, key=lambda m: (method_order(m), m))


def label(layouts: list[LayoutCells], method: str) -> str:
    return method_name(layouts[0].cells[method].info["method"])


def colours(sizes: dict[str, list[LayoutCells]]) -> dict[str, str]:
    """The declared colour of each method that has one, by method."""
    found = {
        m: method_colour(lay.cells[m].info["method"])
        for layouts in sizes.values()
        for lay in layouts[:1]
        for m in methods_of(layouts)
    }
    return {m: c for m, c in found.items() if c}


# ------------------------------------------------------------------------------------ claims
def share(k: int, n: int) -> str:
    low, high = wilson_ci(k / n, n) if n else (float("nan"), float("nan"))
    return f"{k}/{n} = {100 * k / n:.0f}% [{100 * low:.0f}, {100 * high:.0f}]" if n else ""


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
                    lambda claim=claim, lay=lay: claim.make(NO_PAPER, lay.arm),
                    quoted=claim.quoted,
                )
                if c.verdict == "not checked":
                    continue
                verdicts.append(c.verdict)
                means_ok.append(all(k.estimate > 0 for k in c.checks))
            n = len(verdicts)
            if not n:
                continue
            holds, fails, ordered = (
                verdicts.count("holds"),
                verdicts.count("does not hold"),
                sum(means_ok),
            )
            text = c.text()
            table.append(
                {
                    "size": size,
                    "where": claim.source,
                    "the paper": text,
                    "layouts": n,
                    "holds": share(holds, n),
                    "does not hold": share(fails, n),
                    "means in the claimed order": share(ordered, n),
                }
            )
            for what, k in (("holds", holds), ("does_not_hold", fails), ("means_ordered", ordered)):
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
        low, high = bootstrap_ci(g)
        rows.append(
            {
                "size": size,
                "layouts": len(ok),
                "few-shot without DSS (mean)": f"{without.mean():.2f}",
                "DSS gain (mean [95% CI])": f"{g.mean():.2f} [{low:.2f}, {high:.2f}]",
                "relative gain": f"{100 * g.mean() / without.mean():.1f}%"
                if without.mean()
                else "",
                "layouts with a gain": share(int((g > 0).sum()), len(ok)),
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
        verdict = "holds" if low > 0 else "does not hold" if high < 0 else "not resolved"
        out.append(
            {
                "check": f"DSS gain on {large} − on {small}",
                "estimate [95% CI]": f"{est:.2f} [{low:.2f}, {high:.2f}]",
                "verdict": verdict,
                "estimate": est,
                "ci_low": low,
                "ci_high": high,
            }
        )
    return out


# ------------------------------------------------------------------------------------ features
def fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float] | None:
    """Least-squares line ``y = a + b x``: ``(b, a, b_low, b_high)`` with a 95% t interval of the
    slope; None when ``x`` takes one value (or there are fewer than three points)."""
    if x.size < 3 or np.ptp(x) == 0:
        return None
    b, a = np.polyfit(x, y, 1)
    resid = y - (a + b * x)
    se = np.sqrt(resid @ resid / (x.size - 2) / ((x - x.mean()) @ (x - x.mean())))
    half = t_quantile_975(x.size - 2) * se
    return float(b), float(a), float(b - half), float(b + half)


def data_frame(sizes: dict[str, list[LayoutCells]]) -> pd.DataFrame:
    rows = []
    for size, layouts in sizes.items():
        for lay in layouts:
            feats = features(lay.rows)
            for method in methods_of(layouts):
                v = lay.arm(method).values.to_numpy()
                rows.append(
                    {
                        "size": size,
                        "layout_seed": lay.seed,
                        "maze": lay.maze,
                        "method": method,
                        "label": label(layouts, method),
                        "cell": lay.cells[method].name,
                        "runs": v.size,
                        "collisions_mean": float(v.mean()),
                        "collisions_std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
                        **feats,
                    }
                )
    return pd.DataFrame(rows)


def no_line(x: np.ndarray) -> str:
    """Why a feature has no fitted line: constant over the layouts, or too few of them."""
    return f"constant ({int(x[0])})" if np.ptp(x) == 0 else f"no line: {x.size} layouts"


def feature_rows(df: pd.DataFrame) -> list[dict]:
    out = []
    for size, feature in [(s, f) for s in dict.fromkeys(df["size"]) for f in FEATURES]:
        on = df[df["size"] == size]
        for method in dict.fromkeys(on["method"]):
            m = on[on["method"] == method]
            x, y = m[feature].to_numpy(float), m["collisions_mean"].to_numpy(float)
            line = fit(x, y)
            r = (
                float(np.corrcoef(x, y)[0, 1])
                if line is not None and np.ptp(y) > 0
                else float("nan")
            )
            out.append(
                {
                    "size": size,
                    "feature": feature,
                    "method": m["label"].iloc[0],
                    "slope (collisions per unit) [95% CI]": (
                        f"{line[0]:.3g} [{line[2]:.3g}, {line[3]:.3g}]" if line else no_line(x)
                    ),
                    "r": "" if np.isnan(r) else f"{r:.2f}",
                    "feature range": f"{int(x.min())}-{int(x.max())}",
                }
            )
    return out


# ------------------------------------------------------------------------------------ the section
def generalisation_section(rep, exp: Experiment) -> None:
    """The section (module docstring)."""
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
    df.to_csv(
        rep.out / "tables" / f"{exp.folder}_data.csv",
        index=False,
        lineterminator="\n",
        float_format="%.6g",
    )
    name = f"{exp.folder}.png"
    F.layout_boxes(
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
    )
    rep.figure(
        f"figures/{name}",
        "Mean collisions per run on each generated layout, one box per method and size "
        "(median, quartiles, whiskers to 1.5 IQR, layouts beyond as points; log scale). "
        f"Data: `tables/{exp.folder}_data.csv`.",
    )
    table, data = claim_rows(sizes)
    pd.DataFrame(data).to_csv(
        rep.out / "tables" / f"{exp.folder}_claims.csv",
        index=False,
        lineterminator="\n",
        float_format="%.6g",
    )
    rep.table(
        exp.folder,
        pd.DataFrame(table),
        "The paper's claims on each generated layout: the layouts where the claim holds (every check's 95% "
        "interval on the claimed side), where it does not hold (one on the other side; the rest are not "
        "resolved) and where the layout's mean collisions lie in the claimed order; fraction of layouts with "
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
    F.feature_scatter(df, FEATURES, rep.out / "figures" / name, fit, colours(sizes))
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
