"""The grid's replay (:class:`Replay`): one run of the records drawn into a Rerun recording stream
on the timelines ``step`` and ``episode``: the maze, the obstacles in their category colours, the
unsafe set, the robot's path, the return and the visits (or max Q) per cell; and what every
world's replay shows (:class:`.story.Story`).
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from pipeline.records import Records
from pipeline.records import schema as S

from .notes import EmptyViews
from .panels import heat_rgb, legend_positions, maze_views, note
from .story import FREE, GOAL, NESW, ORANGE, RED, ROBOT, START, Story


class Replay(Story):
    """Run ``run`` of the records ``recs`` of a grid cell drawn into the recording stream ``rec``."""

    def __init__(self, rec, recs: Records, run: int):
        super().__init__(rec, recs, run)
        mz = self.meta.maze
        self.width, self.shape = mz["width"], (mz["height"], mz["width"])
        moves = np.array(mz.get("moves") or list(NESW.values()), np.float32)
        self.moves = moves[:, ::-1]  # as (x, y)
        self.q = {e: v for (_, r, e), v in recs.q_values.items() if r == run}
        self.tick = 0  # the global step the episode being drawn starts at
        self.visits = np.zeros(self.shape[0] * self.width, np.int64)  # the states visited so far

    # ---------------------------------------------------------------- geometry and clock
    def xy(self, cells) -> np.ndarray:
        """Cell centres as (x, y) = (col, row) + 0.5."""
        rows, cols = np.divmod(np.asarray(cells, dtype=np.int64), self.width)
        return np.stack([cols, rows], axis=1).astype(np.float32) + 0.5

    def boxes(self, cells, size: float, **kw):
        return rr.Boxes2D(
            mins=self.xy(cells) - size / 2, sizes=np.full((len(cells), 2), size), **kw
        )

    def when(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """Every event of step ``t`` happens at its global step (the grid has no finer time)."""
        return self.tick + t

    def at(self, moment: float, t: int | None = None) -> None:
        self.rec.set_time("step", sequence=int(moment))

    # ---------------------------------------------------------------- what does not change
    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout, with views that fit this maze and support set; the scores view
        says in its name why it is empty (``empty``)."""
        heat = "max Q per cell" if self.q else "visits per cell (log scale)"
        bounds = legend_positions(*self.shape, len(self.labels) + 2)[1]
        return self.layout(maze_views(name, heat, *self.shape, bounds), empty, timeline="step")

    def draw_static(self) -> None:
        """The maze (cells; obstacles in their category colours, named in the legend right of the
        maze and on hover, so no text covers the robot), the series."""
        grid = np.array([list(r) for r in self.meta.maze["layout"]]).ravel()
        free = np.flatnonzero(grid != "X")
        colours = np.array([{"S": START, "G": GOAL}.get(ch, FREE) for ch in grid[free]], np.uint8)
        self.log("maze/cells", self.boxes(free, 1.0, draw_order=0.0, colors=colours), static=True)
        if obstacles := self.meta.obstacles.get(self.run, []):  # this run's assignment
            boxes = self.boxes(
                [o["cell"] for o in obstacles],
                0.9,
                draw_order=1.0,
                class_ids=[o["category"] for o in obstacles],
                show_labels=False,
                labels=[self.obstacle_label(o) for o in obstacles],
            )
            self.log("maze/obstacles", boxes, static=True)
            n = len(self.labels)
            at = legend_positions(*self.shape, n + 2)[0]
            legend = rr.Points2D(at[:n], radii=0.15, class_ids=np.arange(n), show_labels=True)
            self.log("maze/legend", legend, static=True)
            ends = rr.Points2D(at[n:], radii=0.15, colors=[START, GOAL], labels=["start", "goal"])
            self.log("maze/legend/cells", ends, static=True)
        else:  # no assignment recorded: the obstacle cells in grey
            cells = np.flatnonzero(grid == "X")
            boxes = self.boxes(cells, 0.9, colors=[90, 90, 90], draw_order=1.0)
            self.log("maze/obstacles", boxes, static=True)
        self.log("metrics/return", rr.SeriesLines(names="return"), static=True)

    # ---------------------------------------------------------------- what changes
    def unsafe_arrows(self, pairs: np.ndarray):
        """A_d as red arrows in the maze."""
        return rr.Arrows2D(
            origins=self.xy(pairs[:, 0]),
            vectors=self.moves[pairs[:, 1]] * 0.45,
            colors=RED,
            radii=0.04,
            draw_order=3.0,
        )

    def heat(self, entity: str, values: np.ndarray, what: str) -> None:
        """``values`` per cell as a heat map aligned with the maze (one pixel a cell), with its range below."""
        rgb, lo, hi = heat_rgb(values.reshape(self.shape), log=what == "visits")
        self.log(entity, rr.Image(rgb, draw_order=-5.0))
        below = [self.shape[1] / 2, self.shape[0] + 0.4]
        self.log(f"{entity}/range", note(below, f"{what}: {lo:.4g} (dark) .. {hi:.4g} (yellow)"))

    def begin(self, first: int, empty: EmptyViews) -> None:
        """What every replay starts from (:meth:`.story.Story.begin`), and the visits of the run's
        earlier episodes."""
        super().begin(first, empty)
        earlier = self.steps[self.steps.episode < first].state.to_numpy()
        self.visits = np.bincount(earlier, minlength=self.visits.size)

    def episode(self, e: int, start: float) -> int:
        """Episode ``e`` from global step ``start``; the visits grow by its states. Returns the next
        episode's first step."""
        tick, visits = int(start), self.visits
        self.at(tick)
        ep = self.steps[self.steps.episode == e]
        states, flags = ep.state.to_numpy(), ep["flags"].to_numpy()
        actions = ep.action.to_numpy().astype(np.int64)
        n, at = len(states), self.xy(states)
        self.log_unsafe()
        if e - 1 in self.q:  # the Q table the episode starts from
            self.heat("q_values/max", self.q[e - 1].max(axis=1), "max Q")
        if n:  # one row per recorded step on each of these entities
            ticks = [
                rr.TimeColumn("step", sequence=np.arange(tick, tick + n)),
                rr.TimeColumn("episode", sequence=np.full(n, e)),
            ]
            collided, reselected = (flags & S.FLAG_COLLIDED) != 0, (flags & S.FLAG_RESELECTED) != 0
            colours = np.where(collided[:, None], RED, np.where(reselected[:, None], ORANGE, ROBOT))
            robot, radii = np.tile(ROBOT, (n, 1)), np.full(n, 0.25, np.float32)
            by_entity = {
                "maze/robot": rr.Points2D.columns(positions=at, radii=radii, colors=robot),
                "maze/robot/action": rr.Arrows2D.columns(
                    origins=at, vectors=self.moves[actions] * 0.4, colors=colours.astype(np.uint8)
                ),
                "maze/robot/trajectory": rr.LineStrips2D.columns(
                    strips=[at[: t + 1] for t in range(n)], colors=robot
                ),
                "metrics/return": rr.Scalars.columns(
                    scalars=np.cumsum(ep.reward.to_numpy(np.float64))
                ),
            }
            for entity, columns in by_entity.items():
                self.rec.send_columns(entity, indexes=ticks, columns=columns)
        if not self.q:
            self.heat("derived/visits", visits, "visits")
        visits += np.bincount(states, minlength=visits.size)
        self.tick = tick
        self.events(e, states, actions, flags)
        tick += n
        self.rec.set_time("step", sequence=max(tick - 1, 0))
        if not self.q:
            self.heat("derived/visits", visits, "visits")
        if e in self.q:
            self.heat("q_values/max", self.q[e].max(axis=1), "max Q")
        return tick
