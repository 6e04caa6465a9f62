"""The robot's replay in 3D (:class:`RobotReplay`; docs/robot3d.md "Replay"): one run of a robot
cell's records drawn into a Rerun recording stream on the timelines ``sim_time`` (the simulated
seconds; a whole run: its episodes back to back), ``step`` (the steps, counted across the replayed
episodes, as on the grid) and ``episode``. Its entities: the robot's table in docs/replay.md.

Everything 3D lies under ``world`` (z up), and the only 2D content there is the camera's picture,
under its pinhole (``world/robot/camera``): the picture's own 2D view looks through it. Beside the
scene: the return and collisions of the episode so far (``metrics``), the legend in words
(``legend``), and what every world's replay shows (:class:`.story.Story`), each at the moment it
happened.

What the robot's records say (its path, its moments, its world) comes from a
:class:`pipeline.robot.replay.RobotRun`, handed in by :func:`.build.build_replay`'s ``worlds``
(``replay`` cannot import ``robot``: .importlinter).
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from pipeline import palette
from pipeline.records import Records

from .notes import EmptyViews
from .panels import colour
from .scene3d import (
    LEGEND_TEXT,
    MARGIN,
    MARKS,
    corners,
    legend_positions,
    legend_text,
    log_robot,
    log_scene,
    overview_eye,
    yaw_quaternions,
)
from .story import ORANGE, RED, ROBOT, Story

WORLD = "world"
HIT_RADIUS, STOP_RADIUS, LEGEND_RADIUS = 0.12, 0.09, 0.1  # m: the marks' balls
MARK_HEIGHT, PATH_HEIGHT = 0.15, 0.02  # m above the floor
STOP_AHEAD = 0.3  # of a cell: a stop's ball, ahead of the robot that stopped
#: The marks an episode leaves in the scene (``world/<name>``): their balls' colour and radius.
MARK_STYLES = {"collisions": (RED, HIT_RADIUS), "stops": (ORANGE, STOP_RADIUS)}


class RobotReplay(Story):
    """Run ``run`` of the records ``recs`` of a robot cell drawn in 3D into the recording stream
    ``rec`` (the module docstring); ``robot``: the run as its records say
    (:class:`pipeline.robot.replay.RobotRun`, checked)."""

    picture_entity = f"{WORLD}/robot/camera/image"
    unsafe_entity = f"{WORLD}/unsafe"

    def __init__(self, rec, recs: Records, run: int, robot):
        super().__init__(rec, recs, run)
        robot.check(self.steps, self.recog)
        side = float(robot.camera.size)
        self.picture_box = ((0.0, 0.0), (side, side))
        self.robot, self.path, self.start, self.step0 = robot, None, 0.0, 0
        #: The episode's marks so far (x, y, label), by name (:data:`MARK_STYLES`).
        self.marks: dict[str, list[tuple[float, float, str]]] = {}

    # ---------------------------------------------------------------- the clock
    def when(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """The simulated second of an event of step ``t`` of the episode being drawn, in the
        replay (:meth:`pipeline.robot.replay.EpisodePath.moment` after the episode's start)."""
        return self.start + self.path.moment(t, picture, contact)

    def at(self, moment: float, t: int | None = None) -> None:
        """``sim_time`` at ``moment``, ``step`` at step ``t`` of the episode (its first without)."""
        self.rec.set_time("sim_time", duration=float(moment))
        self.rec.set_time("step", sequence=self.step0 + (t or 0))

    # ---------------------------------------------------------------- what does not change
    def floor(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The maze's floor inside its walls: (x range, y range) in m."""
        half_width = self.robot.layout.width * self.robot.cell / 2
        half_height = self.robot.layout.height * self.robot.cell / 2
        return (-half_width, half_width), (-half_height, half_height)

    def legend_at(self) -> np.ndarray:
        """Where the legend beside the maze puts its rows: the categories, then :data:`MARKS`."""
        return legend_positions(*self.floor(), len(self.labels) + len(MARKS))

    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout: the whole maze in 3D from the south (the legend beside it in
        view) over the return and collisions so far, the live picture through the camera, and the
        views every replay has, with the legend in words."""
        (x0, x1), (y0, y1) = self.floor()
        legend = self.legend_at()
        position, target = overview_eye(  # the floor, its walls and the legend with its names
            (x0 - MARGIN, legend[:, 0].max() + LEGEND_TEXT),
            (min(y0, legend[:, 1].min()) - MARGIN, y1 + MARGIN),
        )
        scene = rrb.Spatial3DView(
            origin=WORLD,
            name=f"3D: {name}",
            contents=["$origin/**", f"- {self.picture_entity}/note"],
            eye_controls=rrb.EyeControls3D(
                kind=rrb.Eye3DKind.Orbital, position=position, look_target=target, eye_up=[0, 0, 1]
            ),
        )
        series = rrb.TimeSeriesView(origin="metrics", name="this episode so far")
        camera = rrb.Spatial2DView(
            origin=f"{WORLD}/robot/camera",
            name="live picture" + (": none, see below" if empty.recognition else ""),
        )
        world = rrb.Vertical(scene, series, row_shares=[5, 1])
        return self.layout(
            world, empty, picture=camera, legend="legend", timeline="sim_time", shares=(4, 2, 3)
        )

    def draw_static(self) -> None:
        """The scene, the start and goal tiles, a dot under each obstacle in its category's colour
        (named on hover), the robot (its pose: per tick, :meth:`episode`), the legend, the series."""
        self.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log_scene(self.rec, *self.robot.scene(), root=f"{WORLD}/scene")
        robot, cell = self.robot, self.robot.cell
        obstacles = robot.obstacles
        under = robot.centres([o["cell"] for o in obstacles])
        dots = rr.Points3D(
            np.c_[under, np.full(len(under), 0.01)],
            radii=0.08,
            class_ids=[o["category"] for o in obstacles],
            labels=[self.obstacle_label(o) for o in obstacles],
            show_labels=False,
        )
        self.log(f"{WORLD}/obstacles", dots, static=True)
        ends = robot.centres([robot.layout.start, robot.layout.goal])
        tiles = rr.Boxes3D(
            centers=np.c_[ends, np.full(2, 0.004)],
            half_sizes=[[0.45 * cell, 0.45 * cell, 0.002]] * 2,
            colors=[palette.rgb(MARKS["start"]), palette.rgb(MARKS["goal"])],
            labels=["start", "goal"],
            show_labels=True,
            fill_mode="solid",
        )
        self.log(f"{WORLD}/cells", tiles, static=True)
        log_robot(self.rec, f"{WORLD}/robot", robot.half_sizes, robot.camera)
        n, at = len(self.labels), self.legend_at()
        legend = rr.Points3D(
            np.c_[at, np.full(len(at), MARK_HEIGHT)],
            radii=LEGEND_RADIUS,
            colors=[colour(c) for c in range(n)] + [palette.rgb(h) for h in MARKS.values()],
            labels=self.labels + list(MARKS),
            show_labels=True,
        )
        self.log(f"{WORLD}/legend", legend, static=True)
        words = rr.TextDocument(legend_text(self.labels), media_type="text/markdown")
        self.log("legend", words, static=True)
        for name, rgb in (("return", ROBOT), ("collisions", RED)):
            self.log(f"metrics/{name}", rr.SeriesLines(names=name, colors=[rgb]), static=True)

    # ---------------------------------------------------------------- what changes
    def unsafe_arrows(self, pairs: np.ndarray):
        """A_d as red arrows on the floor, from each pair's cell centre toward its move."""
        heading, reach, n = self.robot.headings(pairs[:, 1]), 0.45 * self.robot.cell, len(pairs)
        return rr.Arrows3D(
            origins=np.c_[self.robot.centres(pairs[:, 0]), np.full(n, 0.03)],
            vectors=np.c_[reach * np.cos(heading), reach * np.sin(heading), np.zeros(n)],
            colors=RED,
            radii=0.02,
        )

    def episode(self, e: int, start: float) -> float:
        """Episode ``e`` from ``start`` (s on ``sim_time``); returns when the next one starts."""
        steps, seen = self.steps[self.steps.episode == e], self.recog[self.recog.episode == e]
        self.path, self.start = self.robot.episode(e, steps, seen), start
        poses, n = self.path.poses, len(self.path.poses)
        starts = np.array([self.path.start_tick(t) for t in range(len(steps))], np.int64)
        step = self.step0 + np.maximum(np.searchsorted(starts, np.arange(n), side="right") - 1, 0)

        def index(ticks):
            ticks = np.asarray(ticks, np.int64)
            return [
                rr.TimeColumn("sim_time", duration=start + poses[ticks, 0]),
                rr.TimeColumn("step", sequence=step[ticks]),
                rr.TimeColumn("episode", sequence=np.full(len(ticks), e)),
            ]

        self.at(start)
        self.log_unsafe()
        self.marks = {name: [] for name in MARK_STYLES}
        for name in self.marks:
            self.log(f"{WORLD}/{name}", rr.Clear(recursive=False))
        self.rec.send_columns(
            f"{WORLD}/robot",
            indexes=index(np.arange(n)),
            columns=rr.Transform3D.columns(
                translation=np.c_[poses[:, 1:3], np.zeros(n)],
                quaternion=yaw_quaternions(poses[:, 3]),
            ),
        )
        self.path_so_far(index)
        self.log_series(index, steps.reward.to_numpy(np.float64), starts)
        for t in sorted(self.path.contact_tick):
            self.at(self.when(t, contact=True), t)
            label = f"collision: ep {e} step {t}{self.collided_where(t)}"
            self.add_mark("collisions", *self.contact(t), label)
        states, actions, flags = (steps[c].to_numpy() for c in ("state", "action", "flags"))
        self.events(e, states, actions, flags)
        self.step0 += len(steps)
        return start + self.path.seconds

    def log_series(self, index, rewards: np.ndarray, starts: np.ndarray) -> None:
        """The episode's return so far at each step's end (steps begin at the ticks ``starts``) and
        its collisions so far, a step up at each contact; ``index``: ticks -> time columns."""
        ends = np.r_[0, starts[1:], len(self.path.poses) - 1][: len(rewards) + 1]
        self.rec.send_columns(
            "metrics/return",
            indexes=index(ends),
            columns=rr.Scalars.columns(scalars=np.r_[0.0, np.cumsum(rewards)][: len(ends)]),
        )
        contacts = self.path.contacts[:, 0].astype(np.int64)
        k = len(contacts)
        before_after = np.c_[np.arange(k), np.arange(1, k + 1)].ravel()  # the count at a contact
        self.rec.send_columns(
            "metrics/collisions",
            indexes=index(np.r_[0, np.repeat(contacts, 2)]),
            columns=rr.Scalars.columns(scalars=np.r_[0, before_after].astype(np.float64)),
        )

    def path_so_far(self, index) -> None:
        """The path on the floor up to every tick: ``world/path`` through its corners so far (a row
        at each corner, :func:`.scene3d.corners`), ``world/path/leg`` from the last corner to the
        robot (a row a tick); together the path within 2 mm, in little data."""
        xy = self.path.poses[:, 1:3]
        floor = np.c_[xy, np.full(len(xy), PATH_HEIGHT)]
        kept = corners(xy)
        last = kept[np.searchsorted(kept, np.arange(len(xy)), side="right") - 1]
        for entity, ticks, strips in (
            (f"{WORLD}/path", kept, [floor[kept[: i + 1]] for i in range(len(kept))]),
            (f"{WORLD}/path/leg", np.arange(len(xy)), [floor[[c, i]] for i, c in enumerate(last)]),
        ):
            n = len(ticks)
            lines = rr.LineStrips3D.columns(
                strips=strips,
                colors=np.tile(ROBOT, (n, 1)).astype(np.uint8),
                radii=np.full(n, 0.012, np.float32),
            )
            self.rec.send_columns(entity, indexes=index(ticks), columns=lines)

    def contact(self, t: int) -> tuple[float, float]:
        """Where step ``t``'s collision touched (x, y in m)."""
        k = sorted(self.path.contact_tick).index(t)
        return float(self.path.contacts[k, 1]), float(self.path.contacts[k, 2])

    def collided_where(self, t: int) -> str:
        """`` into the chair #0 r1 at (x, y) = (0.52, -1.03) m``: the obstacle nearest the contact."""
        if self.path is None or t not in self.path.contact_tick:
            return ""
        x, y = self.contact(t)
        obstacles = self.robot.obstacles
        centres = self.robot.centres([o["cell"] for o in obstacles])
        hit = obstacles[int(np.argmin(np.hypot(centres[:, 0] - x, centres[:, 1] - y)))]
        return f" into the {self.obstacle_label(hit)} at (x, y) = ({x:.2f}, {y:.2f}) m"

    def stopped(self, r, number: int) -> None:
        """A ball before the obstacle the robot looked at (the episode's ``number``-th picture) and
        stopped for, at the current time (the picture's moment)."""
        tick = int(self.path.pictures[number])
        x, y, yaw = self.path.poses[tick, 1:4]
        ahead = STOP_AHEAD * self.robot.cell
        x, y = float(x + ahead * math.cos(yaw)), float(y + ahead * math.sin(yaw))
        label = f"stop: step {int(r.step)}, recognised {self.cat(int(r.predicted))}"
        self.add_mark("stops", x, y, label)

    def add_mark(self, name: str, x: float, y: float, label: str) -> None:
        """Add the mark ``label`` at (``x``, ``y``) to the episode's ``name`` marks, and show them
        all so far as balls at ``world/<name>`` (:data:`MARK_STYLES`)."""
        marks, (rgb, radius) = self.marks[name], MARK_STYLES[name]
        marks.append((x, y, label))
        xs, ys, labels = zip(*marks)
        self.log(
            f"{WORLD}/{name}",
            rr.Points3D(
                np.c_[xs, ys, np.full(len(marks), MARK_HEIGHT)],
                radii=radius,
                colors=[rgb],
                labels=list(labels),
                show_labels=False,
            ),
        )
