"""The report's section "On a simulated robot" (kind ``robot``; experiment ``robot3d``, issue 38,
docs/robot3d.md): the methods with the camera robot in MuJoCo beside the grid, the same seeds.

Each robot cell is paired with its grid twin by run (:mod:`pipeline.report.robot_cells`); the
robot's moves have the grid's outcomes, so the two differ only in their pictures (live, not
pre-rendered). One table per decision rule (:class:`pipeline.rl.rules.Rule`: the paper's is
Algorithm 1, section 3.2.2; ``open_set`` and ``range`` are ours): the robot is set beside the grid
under one rule only.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.report.figures_beyond import difference_figure
from pipeline.report.formats import estimate
from pipeline.report.robot_cells import Pair, check_cell, pairs, read_extra, recogniser, rule
from pipeline.rl.rules import Rule
from pipeline.stats import bootstrap_difference, describe, wilson_ci
from pipeline.world.pictures import CATEGORIES

#: Each decision rule in words (captions); ``{threshold}``: the cells' recorded threshold.
RULE_WORDS = {
    Rule.paper: "the paper's rule (Algorithm 1, section 3.2.2): a picture stops the robot when its "
    "prediction names the obstacle's true category, so every stop is a right stop",
    Rule.open_set: "the open-set rule: a picture stops the robot when its top relation score is at "
    "least the threshold ({threshold}), whatever category it names",
    Rule.range: "the range sensor alone: the robot stops before every occupied cell ahead, so it "
    "never collides; the picture is still classified and recorded",
}


def mean_ci(values) -> str:
    """``mean [lo, hi]``: the mean over runs and its 95% bootstrap interval."""
    d = describe(values)
    return estimate(d["mean"], d["ci_low"], d["ci_high"])


def paired_difference(a, b) -> str:
    """``mean(a - b) [lo, hi]``: run ``i`` of ``a`` and of ``b`` share a seed (paired bootstrap)."""
    return estimate(*bootstrap_difference(a, b, paired=True), sign="+")


def pair_table(chosen: list[Pair], several_recognisers: bool) -> pd.DataFrame:
    """One row per robot cell and its grid twin: collisions on each; with pictures, their paired
    difference and the false and right stops on each; without, the runs where they are equal."""
    rows = []
    for p in chosen:
        robot, grid = p.on_robot, p.on_grid
        row = {"method": p.method, "maze": p.robot.maze}
        row |= {"recogniser": recogniser(p.robot)} if several_recognisers else {}
        row["runs"] = len(robot.runs)
        row["collisions, grid"] = mean_ci(grid.collisions)
        row["collisions, robot"] = mean_ci(robot.collisions)
        if rule(p.robot) is None:
            same = int(np.sum(robot.collisions == grid.collisions))
            row["runs where robot = grid"] = f"{same} of {len(robot.runs)}"
        else:
            difference = paired_difference(robot.collisions, grid.collisions)
            row["collisions, robot - grid (paired)"] = difference
            for kind in ("false", "right"):
                row[f"{kind} stops, grid"] = mean_ci(getattr(grid, f"{kind}_stops"))
                row[f"{kind} stops, robot"] = mean_ci(getattr(robot, f"{kind}_stops"))
        rows.append(row)
    return pd.DataFrame(rows)


def rule_caption(r: Rule, chosen: list[Pair]) -> str:
    """The caption of rule ``r``'s table (its threshold: the cells' recorded one)."""
    thresholds = sorted({str((p.robot.config or {}).get("threshold")) for p in chosen})
    return (
        f"Decision rule `{r.name}`: {RULE_WORDS[r].format(threshold=', '.join(thresholds))}. "
        "Few-shot methods on the grid (the query pictures) and with the robot in MuJoCo (its live "
        "pictures), the same seeds; per run, mean [95% bootstrap CI] over runs. Robot - grid: the "
        "mean of the run-by-run differences (run r of both meets the same obstacles) with a paired "
        "bootstrap 95% interval; the robot's moves have the grid's outcomes, so a difference comes "
        "from the pictures alone. A stop: a picture after which its (state, action) joined the "
        "unsafe set by recognition; a false stop's prediction names a wrong category, a right "
        "stop's the true one. The robot is set beside the grid under this rule only."
    )


BLIND_CAPTION = (
    "Methods that see no pictures (no decision rule applies): collisions per run (mean [95% "
    "bootstrap CI] over runs) on the grid and with the robot in MuJoCo, the same seeds. They are "
    "equal run by run by construction, not by chance: the robot's moves have the grid's outcomes "
    "(a free neighbour is reached, an obstacle's box is always hit: the motion table checks both "
    "when it is built), and the run's seed makes the agent's choices, so a run where they differ "
    "is a fault of the robot world, not a finding."
)


def _means(pair: Pair, field: str) -> str:
    return f"{getattr(pair.on_robot, field).mean():.2f} ({getattr(pair.on_grid, field).mean():.2f})"


def range_statement(few: list[Pair]) -> str:
    """What recognition adds over the range sensor, and at what cost in false stops: per maze and
    method, the collisions under each rule (the range sensor's against the rules that look at the
    picture) and the false stops under ``open_set`` and ``range`` (``paper`` has none: it stops only
    on the true category). From the records; robot first, the grid in brackets."""
    by = {(p.method, p.robot.maze, rule(p.robot)): p for p in few}
    text = "**What recognition adds over the range sensor, and at what cost in false stops.** "
    ranged = [p for p in few if rule(p.robot) == Rule.range]
    if ranged:
        worst = max(max(p.on_robot.collisions.max(), p.on_grid.collisions.max()) for p in ranged)
        text += "The range sensor alone stops before every occupied cell ahead: " + (
            f"none of its {sum(len(p.on_robot.runs) for p in ranged)} robot runs (nor their grid "
            "twins) collided. "
            if worst == 0
            else f"yet a run collided {int(worst)} times (robot or grid): check its cells. "
        )
    text += (
        "The rules that look at the picture stop only where it says so (`paper`: its prediction "
        "names the true category, so no stop is false; `open_set`: its top score reaches the "
        "threshold, whatever it names), and each obstacle they let pass is a collision. A false "
        "stop is a stop whose picture names a wrong category. Per run, on the robot (on the grid "
        "in brackets):\n\n"
    )
    fewest = []
    for method, maze in dict.fromkeys((p.method, p.robot.maze) for p in few):
        here = {r: by[method, maze, r] for r in Rule if (method, maze, r) in by}
        parts = [
            "collisions "
            + ", ".join(f"{_means(p, 'collisions')} under `{r.name}`" for r, p in here.items())
        ]
        false = [
            f"{_means(p, 'false_stops')} under `{r.name}`"
            for r, p in here.items()
            if r != Rule.paper
        ]
        parts += ["false stops " + ", ".join(false)] if false else []
        text += f"- {maze}, {method}: " + "; ".join(parts) + ".\n"
        if Rule.range in here and len(here) > 1:
            means = {r: p.on_robot.collisions.mean() for r, p in here.items()}
            fewest.append(means[Rule.range] <= min(means.values()))
    if fewest:
        verdict = ": recognition adds the category of what it stops before, not fewer collisions"
        text += f"\nOn the robot the range sensor collides least in {sum(fewest)} of {len(fewest)} "
        text += f"rows{verdict if all(fewest) else ''}.\n"
    return text


#: The columns of the accuracy table of each recogniser: which pictures, from which cell of a pair.
SIDES = (("grid", "query pictures (grid)"), ("robot", "live pictures (robot)"))


def accuracy_table(few: list[Pair]) -> pd.DataFrame:
    """Per rule and category, the share of pictures whose prediction names the true category
    (95% Wilson CI): the grid's query pictures beside the robot's live pictures, per recogniser."""
    seen = pd.concat(
        getattr(p, side)
        .recognitions[["true", "predicted"]]
        .assign(rule=rule(p.robot).value, column=f"{recogniser(p.robot)}: {label}")
        for p in few
        for side, label in SIDES
    )
    columns = [
        f"{n}: {label}" for n in sorted({recogniser(p.robot) for p in few}) for _, label in SIDES
    ]
    rows = []
    for r, c in ((r, c) for r in sorted(set(seen["rule"])) for c in range(len(CATEGORIES))):
        row = {"rule": Rule(r).name, "category": CATEGORIES[c]}
        for column in columns:
            sel = seen[(seen["rule"] == r) & (seen["column"] == column) & (seen["true"] == c)]
            share, n = float((sel["predicted"] == c).mean()) if len(sel) else 0.0, len(sel)
            row[column] = f"{estimate(share, *wilson_ci(share, n))} (n={n})" if n else "-"
        rows.append(row)
    return pd.DataFrame(rows)


ACCURACY_CAPTION = (
    "Recognition accuracy per decision rule and category: every picture the few-shot cells "
    "classified, whether its prediction names its true category (share [95% Wilson CI], n "
    "pictures). Grid: the pre-rendered query pictures; robot: the robot's own live pictures. "
    "Which pictures are met depends on the rule, so robot and grid are set side by side within a "
    "rule only."
)


def figure(rep, exp, found: list[Pair], several: bool) -> None:
    """The paired differences, robot minus grid, one row per robot cell, coloured by rule."""
    rows = [
        (
            f"{p.method}, {p.robot.maze}" + (f", {recogniser(p.robot)}" if several else ""),
            rule(p.robot).name if rule(p.robot) is not None else "no pictures",
            p.on_robot.collisions,
            p.on_grid.collisions,
        )
        for p in found
    ]
    name = f"{exp.folder}_robot_minus_grid.png"
    difference_figure(rows, rep.out / "figures" / name)
    rep.figure(
        f"figures/{name}",
        "Collisions per run of the camera robot minus its grid twin's (the same run seeds, so the "
        "same obstacles), per robot cell, one colour and marker per decision rule: the mean of "
        "the run-by-run differences with its 95% paired bootstrap interval; 0 is no difference.",
    )


def robot_kind(rep, exp, experiments) -> None:
    """The section: the statement on the range sensor (:func:`range_statement`), the paired
    differences as a figure, a table per decision rule, the methods that see no pictures,
    recognition accuracy per category, the real-time factor (when the benchmark holds it); the
    other ``experiments`` are not used."""
    cells = list(exp.cells.values())
    extras = {cell.name: read_extra(cell) for cell in cells}
    for cell in cells:
        check_cell(cell, extras[cell.name])
    found = pairs(cells, extras)
    few = [p for p in found if rule(p.robot) is not None]
    blind = [p for p in found if rule(p.robot) is None]
    several = len({recogniser(p.robot) for p in few}) > 1
    if not found:
        rep.add("No robot cell (world robot3d) has records.\n")
    if few:
        rep.add(range_statement(few))
    if found:
        figure(rep, exp, found, several)
    for r in Rule:
        chosen = [p for p in few if rule(p.robot) == r]
        if chosen:
            rep.table(
                f"{exp.folder}_{r.name}", pair_table(chosen, several), rule_caption(r, chosen)
            )
    if blind:
        rep.table(f"{exp.folder}_no_pictures", pair_table(blind, False), BLIND_CAPTION)
        same = [np.array_equal(p.on_robot.collisions, p.on_grid.collisions) for p in blind]
        if differ := [p.robot.name for p, equal in zip(blind, same) if not equal]:
            rep.add(
                f"**Robot and grid differ** in cells {', '.join(differ)}: their moves should have "
                "the grid's outcomes; the robot world has a fault.\n"
            )
    if few:
        rep.table(f"{exp.folder}_recognition", accuracy_table(few), ACCURACY_CAPTION)
