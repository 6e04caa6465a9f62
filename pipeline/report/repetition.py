"""The ``repetition`` section kind: what drives the dynamic support set's gain?
(``conf/experiment/repetition.yaml``, issue 29.)

On the paper's 5x5 nine of the ten physical obstacles appear once, so a picture substituted after a
collision is never seen again; the 7x7 and 11x11 put 16 and 49 obstacles on the same ten. The
experiment holds the size (11x11) and sets how often each obstacle appears, ``r`` = obstacles / 10
(:data:`~pipeline.world.pictures.N_PHYSICAL_OBSTACLES`; each layout set has its own obstacle
count), and runs few-shot reasoning without and with the DSS under several recognisers on every
layout. A recogniser that learns only the substituted picture itself (``fixed_accuracy``) gains
from repetition alone; a network gains also from what a new support picture teaches it about
the other pictures of its category.

The section: the DSS gain and the relative gain (gain / collisions without the DSS) against r per
recogniser, beside Table 3's at each maze's own r (9, 16, 49 obstacles: r = 0.9, 1.6, 4.9), and the
verdict: how much of Table 3's growth of the relative gain from the 5x5 to the 11x11 repetition
accounts for (:func:`verdict`). The relative gain is its scale: the absolute gain also grows with
how many obstacles the robot meets, which changes with the maze for reasons other than repetition.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.report.checks import Data, Missing
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.figures_beyond import gain_curves
from pipeline.report.formats import estimate, interval
from pipeline.report.names import PAPER_RECOGNISER, recogniser_name, recogniser_of
from pipeline.report.parts import section_data
from pipeline.report.repetition_sources import (
    SETTINGS,
    by_layout,
    layout_row,
    source_rows,
    sources_section,
)
from pipeline.world.pictures import N_PHYSICAL_OBSTACLES

RESAMPLES, SEED = 2000, 0
#: Few-shot reasoning without and with the DSS, every substituted picture seen (the split's ends).
WITHOUT, WITH = SETTINGS[0], SETTINGS[-1]


def table3_paper(experiments: list[Experiment]) -> dict[str, tuple[float, float]]:
    """The paper's Table 3, few-shot without and with the DSS (ways pooled), by maze, smallest
    first: the ``paper`` numbers of table3's ``fewshot`` and ``fewshot_dss`` groups, as its
    records keep its report block (``conf/experiment/table3.yaml``)."""
    table3 = next((e for e in experiments if e.name == "table3"), None)
    paper = {g.key: g.paper for g in table3.spec.groups} if table3 else {}
    without, with_ = paper.get("fewshot", {}), paper.get("fewshot_dss", {})
    mazes = sorted(set(without) & set(with_), key=lambda m: np.prod([int(x) for x in m.split("x")]))
    return {m: (float(without[m]), float(with_[m])) for m in mazes}


def recogniser_label(cell: Cell) -> str:
    """The recogniser a cell ran, in words: its display name, with its accuracy ``p`` where it
    takes one (``fixed accuracy p = 0.55``)."""
    node = (cell.config or {}).get("recogniser") or {}
    name = recogniser_name(recogniser_of(cell.info, cell.config))
    return f"{name} p = {node['p']}" if "p" in node else name


def layout_rows(exp: Experiment) -> pd.DataFrame:
    """One row per (layout, recogniser) with both methods: r, the layout, mean collisions per run
    without and with the DSS, and their paired per-run difference's mean (the layout's gain).
    Cells whose recogniser sees only some substituted pictures (``learn_from``) are the split's
    (:mod:`.repetition_sources`), not these rows'."""
    rows = []
    for (maze, label), cells in by_layout(exp, recogniser_label).items():
        if {WITHOUT, WITH} <= set(cells):
            without, with_ = cells[WITHOUT].collisions_by_run(), cells[WITH].collisions_by_run()
            rows.append(
                layout_row(label, maze)
                | {
                    "runs": len(without),
                    "without_dss": without.mean(),
                    "with_dss": with_.mean(),
                    "gain": (without - with_).mean(),
                }
            )
    return pd.DataFrame(rows)


def resampled(df: pd.DataFrame, rng: np.random.Generator | None) -> tuple[np.ndarray, np.ndarray]:
    """Per r (sorted), the mean gain and the relative gain over the layouts of ``df`` (one
    recogniser), the layouts resampled with replacement when ``rng`` is given."""
    gain, rel = [], []
    for _, g in df.groupby("r", sort=True):
        pick = rng.integers(0, len(g), len(g)) if rng is not None else np.arange(len(g))
        w, d = g["without_dss"].to_numpy()[pick], g["gain"].to_numpy()[pick]
        gain.append(d.mean())
        rel.append(d.mean() / w.mean() if w.mean() else np.nan)
    return np.array(gain), np.array(rel)


def curve_table(df: pd.DataFrame) -> tuple[list[dict], dict[str, dict]]:
    """Table rows per recogniser and r, and the curves (r, gain, relative gain, with intervals)."""
    rows, curves = [], {}
    rng = np.random.default_rng(SEED)
    for label, g in df.groupby("recogniser", sort=False):
        rs = np.sort(g["r"].unique())
        gain, rel = resampled(g, None)
        boot = [resampled(g, rng) for _ in range(RESAMPLES)]
        gb, rb = np.array([b[0] for b in boot]), np.array([b[1] for b in boot])
        glo, ghi = np.nanquantile(gb, [0.025, 0.975], axis=0)
        rlo, rhi = np.nanquantile(rb, [0.025, 0.975], axis=0)
        curves[label] = {"r": rs, "gain": (gain, glo, ghi), "relative": (rel, rlo, rhi)}
        for i, r in enumerate(rs):
            at = g[g["r"] == r]
            rows.append(
                {
                    "recogniser": label,
                    "r (each obstacle's cells)": f"{r:g}",
                    "layouts": len(at),
                    "runs per layout": int(at["runs"].iloc[0]),
                    "few-shot without DSS": f"{at['without_dss'].mean():.2f}",
                    "with DSS": f"{at['with_dss'].mean():.2f}",
                    "DSS gain [95% CI]": estimate(gain[i], glo[i], ghi[i]),
                    "relative gain [95% CI]": f"{100 * rel[i]:.1f}% "
                    + interval(rlo[i], rhi[i], 1, 100),
                }
            )
    return rows, curves


def table3_arms(experiments: list[Experiment]) -> dict[str, tuple[float, pd.Series, pd.Series]]:
    """Table 3's cells of the paper's recogniser by maze: (r of the maze, collisions per run without the
    DSS, with it: the four ways averaged per run seed)."""
    data = Data(list(experiments))
    out = {}
    for maze in table3_paper(experiments):
        try:
            without = data.arm("table3", "fewshot", maze)
            with_ = data.arm("table3", "fewshot_dss", maze)
        except Missing:
            continue
        obstacles = sum(row.count("X") for row in without.cells[0].layout)
        out[maze] = (obstacles / N_PHYSICAL_OBSTACLES, without.values, with_.values)
    return out


def at(rs: np.ndarray, values: np.ndarray, r: float) -> float:
    """The curve's value at ``r``: linear between measured r, the end value beyond them."""
    return float(np.interp(r, rs, values))


def verdict(df: pd.DataFrame, t3: dict, label: str) -> tuple[list[dict], dict]:
    """Repetition's share of Table 3's growth from the 5x5 to the 11x11 (module docstring), for
    the relative and the absolute gain, with its bootstrap interval; and the numbers the text
    quotes."""
    g = df[df["recogniser"] == label]
    rs = np.sort(g["r"].unique())
    (r_small, w_s, d_s), (r_large, w_l, d_l) = t3["5x5"], t3["11x11"]
    rng = np.random.default_rng(SEED)

    def one(pick_runs: bool) -> tuple[float, float, float, float]:
        gain, rel = resampled(g, rng if pick_runs else None)
        t = []
        for w, d in ((w_s, d_s), (w_l, d_l)):
            i = rng.integers(0, len(w), len(w)) if pick_runs else np.arange(len(w))
            diff = (w.to_numpy() - d.reindex(w.index).to_numpy())[i]
            t.append((diff.mean(), diff.mean() / w.to_numpy()[i].mean()))
        rel_rep = at(rs, rel, r_large) - at(rs, rel, r_small)
        abs_rep = at(rs, gain, r_large) - at(rs, gain, r_small)
        return rel_rep, t[1][1] - t[0][1], abs_rep, t[1][0] - t[0][0]

    point = one(False)
    boot = np.array([one(True) for _ in range(RESAMPLES)])
    rows, numbers = [], {}
    for k, scale in ((0, "relative gain"), (2, "absolute gain (collisions per run)")):
        share = boot[:, k] / boot[:, k + 1]
        lo, hi = np.nanquantile(share, [0.025, 0.975])
        est = point[k] / point[k + 1]
        unit = 100 if k == 0 else 1
        fmt = (lambda v: f"{100 * v:.1f} points") if k == 0 else (lambda v: f"{v:.2f}")
        rows.append(
            {
                "scale": scale,
                f"11x11 at r = {r_large:g} − at r = {r_small:g} ({label})": fmt(point[k]),
                "Table 3: 11x11 − 5x5 (ours)": fmt(point[k + 1]),
                "repetition's share [95% CI]": f"{100 * est:.0f}% {interval(lo, hi, 0, 100)}",
            }
        )
        numbers[scale] = (est, lo, hi, point[k] * unit, point[k + 1] * unit)
    numbers["r"] = (r_small, r_large)
    return rows, numbers


def words(share: float, lo: float, hi: float) -> str:
    """The share in words, from its estimate and interval."""
    if lo > 0.8:
        return "nearly all of it"
    if hi < 0.2:
        return "little of it"
    return "most of it" if share >= 0.5 else "part of it"


def repetition_section(rep, exp: Experiment, experiments: list[Experiment]) -> None:
    """The section (module docstring)."""
    df = layout_rows(exp)
    if not section_data(rep, exp, df, "No layout of this experiment has both few-shot cells.\n"):
        return
    rows, curves = curve_table(df)
    t3 = table3_arms(experiments)
    beside = {
        f"Table 3, {recogniser_name(PAPER_RECOGNISER)} (ours)": {
            m: (r, (w - d.reindex(w.index)).mean(), 1 - d.mean() / w.mean())
            for m, (r, w, d) in t3.items()
        },
        "Table 3 (paper)": {
            m: (t3[m][0] if m in t3 else np.nan, a - b, 1 - b / a)
            for m, (a, b) in table3_paper(experiments).items()
        },
    }
    name = f"{exp.folder}.png"
    gain_curves(curves, beside, rep.out / "figures" / name)
    rep.add(
        f"Few-shot reasoning without and with the dynamic support set (way 1) on generated 11x11 layouts "
        f"(scattered obstacles) where each of the ten physical obstacles stands on r cells; "
        f"{df.groupby(['recogniser', 'r']).size().min()} layouts per r and recogniser.\n"
    )
    rep.figure(
        f"figures/{name}",
        "The DSS gain (left: collisions per run without minus with it) and the relative gain (right: "
        "gain / collisions without it) against r, one line per recogniser with its 95% bootstrap "
        "interval over layouts; Table 3's at each maze's own r (maze size and r change together there). "
        f"Data: `tables/{exp.folder}_data.csv`.",
    )
    rep.table(
        exp.folder,
        pd.DataFrame(rows),
        "The DSS gain against r (mean collisions per run over layouts; the gain paired on each layout's "
        "run seeds), with 95% bootstrap intervals over layouts (2000 resamples, seed 0).",
    )
    sources = source_rows(exp, recogniser_label)
    if not sources.empty:  # the experiment has learn_from cells
        sources_section(rep, exp, sources, RESAMPLES, SEED)
    label = recogniser_name(PAPER_RECOGNISER)
    if label not in curves or not {"5x5", "11x11"} <= set(t3):
        rep.add(f"No verdict: it needs the {label}'s cells here and Table 3's 5x5 and 11x11.\n")
        return
    vrows, n = verdict(df, t3, label)
    rep.table(
        f"{exp.folder}_verdict",
        pd.DataFrame(vrows),
        "How much of Table 3's growth of the DSS gain from the 5x5 to the 11x11 repetition accounts for: the "
        f"{label}'s gain at one size (11x11) read at the two mazes' r (linear between measured r, the end value "
        "beyond), over Table 3's growth; 95% interval from resampling layouts and Table 3's run seeds together.",
    )
    est, lo, hi, rep_pts, t3_pts = n["relative gain"]
    r_small, r_large = n["r"]
    fixed = next((k for k in curves if k.startswith("fixed")), None)
    net = curves[label]
    extra = (
        f" At r = {net['r'][0]:g}, where a substituted picture is never seen again, the {label} still gains "
        f"{100 * net['relative'][0][0]:.1f}% "
        f"{interval(net['relative'][1][0], net['relative'][2][0], 1, 100)}: what a new support "
        "picture teaches it about the others."
    )
    if fixed is not None:
        c = curves[fixed]
        extra += (
            f" The {fixed} recogniser, which learns only the substituted picture, shows repetition alone: its "
            f"relative gain is {100 * at(c['r'], c['relative'][0], 1):.1f}% at r = 1 and "
            f"{100 * at(c['r'], c['relative'][0], r_large):.1f}% at r = {r_large:g}."
        )
    rep.add(
        f"**Verdict.** Table 3's relative DSS gain grows by {t3_pts:.1f} points from the 5x5 (r = {r_small:g}) "
        f"to the 11x11 (r = {r_large:g}); at one size, raising r from {r_small:g} to {r_large:g} raises it by "
        f"{rep_pts:.1f} points: repetition accounts for {100 * est:.0f}% {interval(lo, hi, 0, 100)} of the "
        f"growth, {words(est, lo, hi)}"
        + ("; the rest comes with the maze's size at the same repetition." if est < 1 else ".")
        + f"{extra}\n"
    )
