"""The report's section "On a simulated robot" (kind ``robot``; experiment ``robot3d``, issue 38,
docs/robot3d.md): the methods with the camera robot in MuJoCo beside the grid, the same seeds.

Every cell, grid or robot, is one ``records.mcap`` of the one runner; a robot cell's recorded config
has ``world: robot3d`` and its ``info`` the robot's motion table (``info.robot``). A robot cell and
its grid twin (same method, maze, decision rule and recogniser) share run seeds: run ``r`` of each
meets the same obstacles, so they are paired by run. The robot's moves have the grid's outcomes
(the motion table checks it), so a robot cell differs from its twin only in its pictures: the
robot's own live pictures instead of the pre-rendered query pictures.

* First, what recognition adds over the range sensor and at what cost in false stops
  (:func:`range_statement`).
* One table per decision rule (:class:`pipeline.rl.rules.Rule`; the paper's rule is Algorithm 1,
  section 3.2.2; ``open_set`` and ``range`` are ours) for the few-shot methods: collisions per run
  on the grid and on the robot, their paired difference, and the stops (:func:`stops`) that named
  a wrong (false) or the true (right) category. The robot is set beside the grid under one rule
  only.
* The methods that see no pictures (shield, SSRL): robot and grid collide alike, run by run.
* Recognition accuracy per category: the robot's live pictures beside the grid's query pictures.
* The real-time factor, from the benchmark (``reports/benchmarks/robot3d.json``) when it holds the
  figures read here: wall-clock figures are never in the records.

Only records are read (.importlinter: the report does not import ``pipeline.robot``); a robot cell
whose records do not match its cell, or that has no grid twin, is refused (:func:`check_cell`,
:func:`pairs`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.errors import UserError
from pipeline.records import read_records
from pipeline.records.schema import SOURCE_NAMES
from pipeline.report.experiments import Cell, ReportInputError
from pipeline.report.names import method_name, method_order, recogniser_name, recogniser_of
from pipeline.report.stats import bootstrap_difference, describe, wilson_ci
from pipeline.rl.rules import Rule
from pipeline.world.maze import load_layout
from pipeline.world.pictures import CATEGORIES

BENCHMARK = Path("reports/benchmarks/robot3d.json")

#: The unsafe additions of a stop (records schema ``UnsafeAdditions.source``).
RECOGNITION = SOURCE_NAMES.index("recognition")
#: What identifies the picture of a stop: the recognition and its unsafe addition share it.
STOP_KEY = ["run", "episode", "step", "state", "action"]

#: Each decision rule in words (captions); ``{threshold}`` is the cells' recorded threshold.
RULE_WORDS = {
    Rule.paper: "the paper's rule (Algorithm 1, section 3.2.2): a picture stops the robot when its "
    "prediction names the obstacle's true category, so every stop is a right stop",
    Rule.open_set: "the open-set rule: a picture stops the robot when its top relation score is at "
    "least the threshold ({threshold}), whatever category it names",
    Rule.range: "the range sensor alone: the robot stops before every occupied cell ahead, so it "
    "never collides; the picture is still classified and recorded",
}


def world(cell: Cell) -> str:
    """The cell's world as recorded (``grid`` or ``robot3d``)."""
    return (cell.config or {}).get("world", "grid")


def rule(cell: Cell) -> Rule | None:
    """The cell's decision rule as recorded; None when its method looks at no pictures (the
    recorded default rule then applies to nothing)."""
    if recogniser_of(cell.info, cell.config) is None:
        return None
    name = (cell.config or {}).get("rule", "paper")
    if name not in Rule.__members__:
        raise ReportInputError(
            f"{cell.path}: decision rule {name!r} is none of {', '.join(Rule.__members__)}"
        )
    return Rule[name]


def recogniser(cell: Cell) -> str:
    """The display name of the recogniser a cell ran ("none": its method looks at no pictures)."""
    kind = recogniser_of(cell.info, cell.config)
    return recogniser_name(kind) if kind else "none"


@dataclass
class Extra:
    """What a cell's records hold beyond the report's :class:`Cell`."""

    robot: dict | None
    """The robot's motion table (the ``info`` metadata's ``robot``; None on the grid)."""
    recognised: pd.DataFrame
    """The unsafe additions by recognition (:data:`STOP_KEY` columns); empty for a method that
    sees no pictures."""


def read_extra(cell: Cell) -> Extra:
    """:class:`Extra` of ``cell``, read from its records; of a method that sees no pictures only
    its first episode (it needs the metadata alone)."""
    window = {} if rule(cell) is not None else {"run": int(cell.runs()[0]), "episode": 0}
    recs = read_records(cell.path, pictures=False, **window)
    added = recs.unsafe.loc[recs.unsafe["source"] == RECOGNITION, STOP_KEY]
    return Extra(recs.meta.info.get("robot"), added.astype("int64"))


def check_cell(cell: Cell, extra: Extra) -> None:
    """Refuse records that do not match their cell: the recorded maze must be the layout of the
    maze its recorded config names and of the maze the experiment declares for the cell's folder (a
    file copied from another cell fails this); a robot cell (``world: robot3d``) must hold its
    motion table (``info.robot``) for the cell size it ran with (``robot.cell``)."""
    config = cell.config or {}
    declared = ((config.get("experiment") or {}).get("cells") or {}).get(cell.name) or {}
    for where, maze in (
        ("its recorded config", config.get("maze")),
        (f"the experiment's cell {cell.name}", declared.get("maze")),
    ):
        if maze is None:
            continue
        try:
            rows = list(load_layout(maze).rows)
        except UserError as exc:
            raise ReportInputError(
                f"{cell.path}: cannot load maze {maze!r} named by {where} ({exc})"
            ) from None
        if rows != list(cell.layout):
            raise ReportInputError(
                f"{cell.path}: the records hold a {len(cell.layout[0])}x{len(cell.layout)} maze "
                f"({'/'.join(cell.layout)}), not maze {maze!r} of {where}; these are another "
                f"cell's records: re-run the trials of {cell.name}"
            )
    if world(cell) != "robot3d":
        return
    table = extra.robot
    if not table:
        raise ReportInputError(
            f"{cell.path}: a robot cell (world robot3d) whose records hold no motion table "
            "(info.robot); re-run its trials"
        )
    ran = (config.get("robot") or {}).get("cell")
    if table.get("cell") != ran:
        raise ReportInputError(
            f"{cell.path}: the motion table is for {table.get('cell')} m cells, but the cell ran "
            f"with robot.cell={ran}; re-run its trials"
        )


def stops(cell: Cell, extra: Extra) -> pd.DataFrame:
    """The recognitions that stopped the robot: those whose (run, episode, step, state, action) has
    an unsafe addition by recognition (each dangerous (s, a) is recognised at most once a run: it
    then joins A_d). A right stop's prediction names the true category, a false stop's another."""
    seen = cell.recognitions
    hit = pd.MultiIndex.from_frame(seen[STOP_KEY].astype("int64")).isin(
        pd.MultiIndex.from_frame(extra.recognised)
    )
    return seen[hit]


@dataclass
class PerRun:
    """A cell's figures per run, in the order of its runs (:meth:`Cell.runs`)."""

    runs: np.ndarray
    collisions: np.ndarray
    right_stops: np.ndarray
    false_stops: np.ndarray


def per_run(cell: Cell, extra: Extra) -> PerRun:
    """Collisions, right stops and false stops of each run of ``cell``."""
    runs = cell.runs()
    collisions = cell.episodes.groupby("run")["collisions"].sum().reindex(runs).to_numpy()
    if rule(cell) is None:
        zero = np.zeros(len(runs), dtype=np.int64)
        return PerRun(runs, collisions, zero, zero)
    stopped = stops(cell, extra)
    right = stopped["predicted"] == stopped["true"]

    def count(rows: pd.DataFrame) -> np.ndarray:
        return rows.groupby("run").size().reindex(runs, fill_value=0).to_numpy()

    return PerRun(runs, collisions, count(stopped[right]), count(stopped[~right]))


def twin_key(cell: Cell) -> tuple:
    """What a robot cell and its grid twin share: the method (all its recorded fields), the maze,
    the decision rule, the recogniser and, under the open-set rule, the threshold."""
    threshold = (cell.config or {}).get("threshold") if rule(cell) == Rule.open_set else None
    method = json.dumps(cell.info["method"], sort_keys=True)
    return (method, cell.maze, rule(cell), recogniser(cell), threshold)


@dataclass
class Pair:
    """A robot cell, its grid twin and their figures per run (paired by run)."""

    robot: Cell
    grid: Cell
    on_robot: PerRun
    on_grid: PerRun

    @property
    def order(self) -> tuple:
        size = len(self.robot.layout) * len(self.robot.layout[0])
        return (method_order(self.robot.method), size, self.robot.maze, recogniser(self.robot))

    @property
    def method(self) -> str:
        return method_name(self.robot.info["method"])


def pairs(cells: list[Cell], extras: dict[str, Extra]) -> list[Pair]:
    """Every robot cell with its grid twin (:func:`twin_key`), in the tables' order. A robot cell
    without exactly one grid twin, or whose runs are not its twin's, is refused."""
    grid: dict[tuple, list[Cell]] = {}
    for cell in cells:
        if world(cell) == "grid":
            grid.setdefault(twin_key(cell), []).append(cell)
    out = []
    for cell in cells:
        if world(cell) != "robot3d":
            continue
        twins = grid.get(twin_key(cell), [])
        if len(twins) != 1:
            what = "no grid twin" if not twins else f"{len(twins)} grid twins"
            raise ReportInputError(
                f"{cell.path}: a robot cell with {what} (a grid cell with the same method, maze "
                f"{cell.maze}, rule, recogniser and threshold{': ' if twins else ''}"
                f"{', '.join(t.name for t in twins)}); record exactly one beside it"
            )
        on_robot = per_run(cell, extras[cell.name])
        on_grid = per_run(twins[0], extras[twins[0].name])
        if not np.array_equal(on_robot.runs, on_grid.runs):
            raise ReportInputError(
                f"{cell.path}: runs {on_robot.runs.tolist()}, but its grid twin "
                f"{twins[0].path} has runs {on_grid.runs.tolist()}; re-run both with one setup"
            )
        out.append(Pair(cell, twins[0], on_robot, on_grid))
    return sorted(out, key=lambda p: p.order)


def mean_ci(values) -> str:
    """``mean [lo, hi]``: the mean over runs and its 95% bootstrap interval."""
    d = describe(values)
    return f"{d['mean']:.2f} [{d['ci_low']:.2f}, {d['ci_high']:.2f}]"


def paired_difference(a, b) -> str:
    """``mean(a - b) [lo, hi]``: run ``i`` of ``a`` and of ``b`` share a seed (paired bootstrap)."""
    estimate, lo, hi = bootstrap_difference(a, b, paired=True)
    return f"{estimate:+.2f} [{lo:+.2f}, {hi:+.2f}]"


def _share(correct: int, n: int) -> str:
    if n == 0:
        return "-"
    lo, hi = wilson_ci(correct / n, n)
    return f"{correct / n:.2f} [{lo:.2f}, {hi:.2f}] (n={n})"


def _row_names(pair: Pair, several_recognisers: bool) -> dict:
    row = {"method": pair.method, "maze": pair.robot.maze}
    if several_recognisers:
        row["recogniser"] = recogniser(pair.robot)
    return row | {"runs": len(pair.on_robot.runs)}


def rule_table(chosen: list[Pair], several_recognisers: bool) -> pd.DataFrame:
    """One row per few-shot robot cell of one rule and its grid twin."""
    rows = []
    for p in chosen:
        robot, grid = p.on_robot, p.on_grid
        rows.append(
            _row_names(p, several_recognisers)
            | {
                "collisions, grid": mean_ci(grid.collisions),
                "collisions, robot": mean_ci(robot.collisions),
                "collisions, robot - grid (paired)": paired_difference(
                    robot.collisions, grid.collisions
                ),
                "false stops, grid": mean_ci(grid.false_stops),
                "false stops, robot": mean_ci(robot.false_stops),
                "right stops, grid": mean_ci(grid.right_stops),
                "right stops, robot": mean_ci(robot.right_stops),
            }
        )
    return pd.DataFrame(rows)


def rule_caption(r: Rule, chosen: list[Pair]) -> str:
    thresholds = sorted({(p.robot.config or {}).get("threshold") for p in chosen}, key=str)
    words = RULE_WORDS[r].format(threshold=", ".join(str(t) for t in thresholds))
    return (
        f"Decision rule `{r.name}`: {words}. Few-shot methods on the grid (the query pictures) and "
        "with the robot in MuJoCo (its live pictures), the same seeds; per run, mean [95% "
        "bootstrap CI] over runs. Robot - grid: the mean of the run-by-run differences (run r of "
        "both meets the same obstacles) with a paired bootstrap 95% interval; the robot's moves "
        "have the grid's outcomes, so a difference comes from the pictures alone. A stop: a "
        "picture after which its (state, action) joined the unsafe set by recognition; a false "
        "stop's prediction names a wrong category, a right stop's the true one. The robot is set "
        "beside the grid under this rule only."
    )


def blind_table(chosen: list[Pair]) -> pd.DataFrame:
    """One row per robot cell of a method that sees no pictures and its grid twin."""
    rows = []
    for p in chosen:
        same = int(np.sum(p.on_robot.collisions == p.on_grid.collisions))
        rows.append(
            _row_names(p, False)
            | {
                "collisions, grid": mean_ci(p.on_grid.collisions),
                "collisions, robot": mean_ci(p.on_robot.collisions),
                "runs where robot = grid": f"{same} of {len(p.on_robot.runs)}",
            }
        )
    return pd.DataFrame(rows)


BLIND_CAPTION = (
    "Methods that see no pictures (no decision rule applies): collisions per run (mean [95% "
    "bootstrap CI] over runs) on the grid and with the robot in MuJoCo, the same seeds. They are "
    "equal run by run by construction, not by chance: the robot's moves have the grid's outcomes "
    "(a free neighbour is reached, an obstacle's box is always hit: the motion table checks both "
    "when it is built), and the run's seed makes the agent's choices, so a run where they differ "
    "is a fault of the robot world, not a finding."
)


def _mean(values) -> str:
    return f"{np.mean(values):.2f}"


def range_statement(few: list[Pair]) -> str:
    """What recognition adds over the range sensor, and at what cost in false stops: per maze and
    method, the collisions under the rules that look at the picture against the range sensor's,
    and the false stops under the open-set rule and the range sensor (the paper's rule has none: it
    stops only on the true category). From the records; robot first, the grid in brackets."""
    by = {(p.method, p.robot.maze, rule(p.robot)): p for p in few}
    text = "**What recognition adds over the range sensor, and at what cost in false stops.** "
    ranged = [p for p in few if rule(p.robot) == Rule.range]
    if ranged:
        worst = max(max(p.on_robot.collisions.max(), p.on_grid.collisions.max()) for p in ranged)
        runs = sum(len(p.on_robot.runs) for p in ranged)
        text += "The range sensor alone stops before every occupied cell ahead: " + (
            f"none of its {runs} robot runs (nor their grid twins) collided. "
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
    lines, fewest = [], []
    for method, maze in dict.fromkeys((p.method, p.robot.maze) for p in few):
        here = {r: by[method, maze, r] for r in Rule if (method, maze, r) in by}
        collisions = [
            f"{_mean(p.on_robot.collisions)} ({_mean(p.on_grid.collisions)}) under `{r.name}`"
            for r, p in here.items()
        ]
        false = [
            f"{_mean(p.on_robot.false_stops)} ({_mean(p.on_grid.false_stops)}) under `{r.name}`"
            for r, p in here.items()
            if r != Rule.paper
        ]
        parts = ["collisions " + ", ".join(collisions)]
        if false:
            parts.append("false stops " + ", ".join(false))
        lines.append(f"- {maze}, {method}: " + "; ".join(parts) + ".")
        if Rule.range in here and len(here) > 1:
            means = {r: p.on_robot.collisions.mean() for r, p in here.items()}
            fewest.append(means[Rule.range] <= min(means.values()))
    text += "\n".join(lines) + "\n"
    if fewest:
        verdict = (
            ": recognition adds the category of what the robot stops before, not fewer collisions"
            if all(fewest)
            else ""
        )
        text += (
            f"\nOn the robot the range sensor collides least in {sum(fewest)} of {len(fewest)} "
            f"rows{verdict}.\n"
        )
    return text


def accuracy_table(few: list[Pair]) -> pd.DataFrame:
    """Per rule and category, the share of pictures whose prediction names the true category: the
    grid's query pictures beside the robot's live pictures, each recogniser apart."""
    rows = []
    names = sorted({recogniser(p.robot) for p in few})
    for r in Rule:
        chosen = [p for p in few if rule(p.robot) == r]
        if not chosen:
            continue
        columns = {}
        for name in names:
            for side, label in (
                ("grid", "query pictures (grid)"),
                ("robot", "live pictures (robot)"),
            ):
                seen = [
                    getattr(p, side).recognitions for p in chosen if recogniser(p.robot) == name
                ]
                columns[f"{name}: {label}"] = pd.concat(seen) if seen else None
        for c, category in enumerate(CATEGORIES):
            row = {"rule": r.name, "category": category}
            for column, frame in columns.items():
                if frame is None:
                    row[column] = "-"
                    continue
                sel = frame[frame["true"] == c]
                row[column] = _share(int((sel["predicted"] == c).sum()), len(sel))
            rows.append(row)
    return pd.DataFrame(rows)


ACCURACY_CAPTION = (
    "Recognition accuracy per decision rule and category: every picture the few-shot cells "
    "classified, whether its prediction names its true category (share [95% Wilson CI], n "
    "pictures). Grid: the pre-rendered query pictures; robot: the robot's own live pictures. "
    "Which pictures are met depends on the rule, so robot and grid are set side by side within a "
    "rule only."
)


def benchmark_line() -> str | None:
    """The real-time factor and physics rates from the benchmark file, when it holds them."""
    if not BENCHMARK.exists():
        return None
    try:
        bench = json.loads(BENCHMARK.read_text())
    except ValueError:
        return None
    cell = bench.get("few_shot_oracle_5x5") if isinstance(bench, dict) else None
    physics = bench.get("physics") if isinstance(bench, dict) else None
    keys = ("physics_steps_per_s_controlled", "pictures_per_s")
    if not isinstance(cell, dict) or "real_time_factor" not in cell:
        return None
    if not isinstance(physics, dict) or not all(k in physics for k in keys):
        return None
    return (
        f"Real-time factor (benchmark `{BENCHMARK}`): {cell['real_time_factor']} simulated seconds "
        f"per wall-clock second; {physics[keys[0]]} physics steps/s under the controller, "
        f"{physics[keys[1]]} live pictures/s.\n"
    )


def robot_kind(rep, exp, paper) -> None:
    """The section: the statement on the range sensor, a table per decision rule, the methods
    that see no pictures, recognition accuracy per category, the real-time factor."""
    cells = list(exp.cells.values())
    extras = {cell.name: read_extra(cell) for cell in cells}
    for cell in cells:
        check_cell(cell, extras[cell.name])
    found = pairs(cells, extras)
    if not found:
        rep.add("No robot cell (world robot3d) has records.\n")
        return
    several = len({recogniser(p.robot) for p in found if rule(p.robot) is not None}) > 1
    few = [p for p in found if rule(p.robot) is not None]
    blind = [p for p in found if rule(p.robot) is None]
    if few:
        rep.add(range_statement(few))
    for r in Rule:
        chosen = [p for p in few if rule(p.robot) == r]
        if chosen:
            rep.table(
                f"{exp.folder}_{r.name}", rule_table(chosen, several), rule_caption(r, chosen)
            )
    if blind:
        rep.table(f"{exp.folder}_no_pictures", blind_table(blind), BLIND_CAPTION)
        differ = [
            p.robot.name
            for p in blind
            if not np.array_equal(p.on_robot.collisions, p.on_grid.collisions)
        ]
        if differ:
            rep.add(
                f"**Robot and grid differ** in cells {', '.join(differ)}: their moves should have "
                "the grid's outcomes; the robot world has a fault.\n"
            )
    if few:
        rep.table(f"{exp.folder}_recognition", accuracy_table(few), ACCURACY_CAPTION)
    line = benchmark_line()
    if line:
        rep.add(line)
