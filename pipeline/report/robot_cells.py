"""The robot section's data (:mod:`pipeline.report.robot`): each robot cell paired with its grid
twin, and their figures per run, from the records alone.

A robot cell (recorded config ``world: robot3d``; its records hold the robot's motion table, the
``info`` metadata's ``robot``) and its grid twin (same method, maze, decision rule, recogniser)
share run seeds: run ``r`` of each meets the same obstacles, so they are paired by run. Records that
do not match their cell, or a robot cell without its grid twin, are refused (:func:`check_cell`,
:func:`pairs`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from pipeline.errors import UserError
from pipeline.records import read_records
from pipeline.records.schema import SOURCE_NAMES
from pipeline.report.experiments import Cell, ReportInputError
from pipeline.report.names import method_name, method_order, recogniser_name, recogniser_of
from pipeline.rl.rules import Rule
from pipeline.world.maze import load_layout

#: The unsafe additions of a stop (records schema ``UnsafeAdditions.source``).
RECOGNITION = SOURCE_NAMES.index("recognition")
#: What a stop's recognition and its unsafe addition share.
STOP_KEY = ["run", "episode", "step", "state", "action"]


def world(cell: Cell) -> str:
    """The cell's world as recorded (``grid`` or ``robot3d``)."""
    return (cell.config or {}).get("world", "grid")


def rule(cell: Cell) -> Rule | None:
    """The cell's decision rule as recorded; None when its method looks at no pictures."""
    if recogniser_of(cell.info, cell.config) is None:
        return None
    name = (cell.config or {}).get("rule", "paper")
    if name not in Rule.__members__:
        raise ReportInputError(
            f"{cell.path}: decision rule {name!r} is none of {[r.name for r in Rule]}"
        )
    return Rule[name]


def recogniser(cell: Cell) -> str:
    """The display name of the recogniser a cell ran ("none": its method looks at no pictures)."""
    kind = recogniser_of(cell.info, cell.config)
    return recogniser_name(kind) if kind else "none"


class Extra(NamedTuple):
    """What a cell's records hold beyond the report's :class:`Cell`."""

    robot: dict | None  # the motion table (the ``info`` metadata's ``robot``); None on the grid
    recognised: pd.DataFrame  # the unsafe additions by recognition (:data:`STOP_KEY` columns)


def read_extra(cell: Cell) -> Extra:
    """:class:`Extra` of ``cell``; of a method that sees no pictures only its first episode is read
    (it needs the metadata alone)."""
    window = {} if rule(cell) is not None else {"run": int(cell.runs()[0]), "episode": 0}
    recs = read_records(cell.path, pictures=False, **window)
    added = recs.unsafe.loc[recs.unsafe["source"] == RECOGNITION, STOP_KEY]
    return Extra(recs.meta.info.get("robot"), added.astype("int64"))


def check_cell(cell: Cell, extra: Extra) -> None:
    """Refuse records that do not match their cell: the recorded maze must be the layout of the
    maze the recorded config names and of the one the experiment declares for the cell's folder (a
    file copied from another cell fails this); a robot cell (``world: robot3d``) must hold its
    motion table for the cell size it ran with (``robot.cell``)."""
    config = cell.config or {}
    declared = ((config.get("experiment") or {}).get("cells") or {}).get(cell.name) or {}
    for maze in dict.fromkeys(m for m in (config.get("maze"), declared.get("maze")) if m):
        try:
            rows = list(load_layout(maze).rows)
        except UserError as exc:
            raise ReportInputError(f"{cell.path}: cannot load maze {maze!r} ({exc})") from None
        if rows != list(cell.layout):
            raise ReportInputError(
                f"{cell.path}: the records hold a {len(cell.layout[0])}x{len(cell.layout)} maze "
                f"({'/'.join(cell.layout)}), not maze {maze!r} of cell {cell.name}; these are "
                "another cell's records: re-run its trials"
            )
    table, ran = extra.robot or {}, (config.get("robot") or {}).get("cell")
    if world(cell) == "robot3d" and table.get("cell") != ran:
        why = f"the motion table of {table['cell']} m cells" if table else "no motion table"
        raise ReportInputError(
            f"{cell.path}: a robot cell (world robot3d, robot.cell={ran}) whose records hold "
            f"{why} (info.robot); re-run its trials"
        )


@dataclass
class PerRun:
    """A cell's figures per run, in the order of its runs (:meth:`Cell.runs`)."""

    runs: np.ndarray
    collisions: np.ndarray
    right_stops: np.ndarray
    false_stops: np.ndarray


def per_run(cell: Cell, extra: Extra) -> PerRun:
    """Collisions, right and false stops of each run. A stop is a recognition whose (run, episode,
    step, state, action) has an unsafe addition by recognition (each dangerous (s, a) is recognised
    at most once a run: it then joins A_d); a right stop's prediction names the true category, a
    false stop's another."""
    runs = cell.runs()
    collisions = cell.collisions_per_run()
    seen = cell.recognitions
    stop = pd.MultiIndex.from_frame(seen[STOP_KEY].astype("int64")).isin(
        pd.MultiIndex.from_frame(extra.recognised)
    )
    right = np.asarray(seen["predicted"] == seen["true"])

    def count(chosen: np.ndarray) -> np.ndarray:
        return seen[chosen].groupby("run").size().reindex(runs, fill_value=0).to_numpy()

    return PerRun(runs, collisions, count(stop & right), count(stop & ~right))


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
    grid, out = [c for c in cells if world(c) == "grid"], []
    for cell in (c for c in cells if world(c) == "robot3d"):
        twins = [g for g in grid if twin_key(g) == twin_key(cell)]
        if len(twins) != 1:
            raise ReportInputError(
                f"{cell.path}: a robot cell with {len(twins) or 'no'} grid twin(s) (grid cells of "
                f"the same method, maze {cell.maze}, rule, recogniser and threshold"
                f"{''.join(f', {t.name}' for t in twins)}); record exactly one beside it"
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
