"""What the replay needs of a robot cell's records (issue 30; docs/robot3d.md "Replay"), checked:
:func:`robot_run` reads one run of a ``records.mcap`` whose recorded config says
``world: robot3d`` (its metadata as :func:`pipeline.records.read_records` gives it) into a
:class:`RobotRun`: the cell size (config ``robot.cell``), the motion table (``info.robot``), the
maze and the run's obstacle placement. :meth:`RobotRun.episode` expands a recorded episode into the
robot's path (:func:`pipeline.robot.motion.episode_path`) and says when each of its events happened
in simulated seconds (:meth:`EpisodePath.moment`); :meth:`RobotRun.scene` builds the run's MuJoCo
world (:func:`pipeline.robot.world.build_world`).

No drawing here: :mod:`pipeline.replay.robot3d` draws it in Rerun with what every replay shares
(``robot`` sits beside ``replay`` in .importlinter; the stage ``replay`` hands :func:`robot_run`
to :func:`pipeline.replay.build_replay`). A missing or odd field is one :class:`RobotRecordError`
naming the file and the field, never a traceback.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.errors import UserError
from pipeline.records import FileMeta
from pipeline.records import schema as S
from pipeline.robot.limits import check_settings
from pipeline.robot.live_world import PICTURE_SIZE
from pipeline.robot.model import CAMERA_FOV, CAMERA_POS, HEIGHT, LENGTH, WIDTH
from pipeline.robot.motion import drive_key, episode_path
from pipeline.robot.sim import CONTROL_HZ, HEADINGS
from pipeline.robot.world import build_world, centre_of
from pipeline.world.layout import Layout, MazeError, parse_layout
from pipeline.world.pictures import INSTANCES_PER_CATEGORY, N_PHYSICAL_OBSTACLES
from pipeline.world.placement import Placement
from pipeline.world.renderer_env import mujoco

OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
#: The robot's body box (m): half its length, width and height (:mod:`pipeline.robot.model`).
HALF_SIZES = (LENGTH / 2, WIDTH / 2, HEIGHT / 2)


@dataclass(frozen=True)
class Camera:
    """The robot's forward camera as the replay draws it (:mod:`pipeline.robot.model`): where it
    sits in the body's frame (m; x forward, z up), its vertical field of view (degrees) and the side
    of the live picture (pixels; the square centre of its 4:3 frame, so the picture's field is the
    vertical one both ways)."""

    position: tuple[float, float, float] = CAMERA_POS
    fov_y: float = CAMERA_FOV[1]
    size: int = PICTURE_SIZE


class RobotRecordError(UserError):
    """A robot cell's records miss a field the replay needs, or hold an odd one; the message names
    the file and the field."""


def _odd(path: Path, field: str, problem: str) -> RobotRecordError:
    return RobotRecordError(f"{path}: {field}: {problem}")


def _number(path: Path, field: str, value) -> float:
    """``value`` as a finite float, else the error naming ``field``."""
    if value is None:
        raise _odd(path, field, "missing")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _odd(path, field, f"{value!r} is not a number")
    if not math.isfinite(value):
        raise _odd(path, field, f"{value!r} is not a finite number")
    return float(value)


def _poses(path: Path, field: str, rows, empty_ok: bool = False) -> np.ndarray:
    """A motion table's poses ``rows`` (n, 3: x mm, y mm, yaw mrad), checked finite; ``empty_ok``:
    a turn by no quarter turn has none."""
    if rows is None:
        raise _odd(path, field, "missing")
    if isinstance(rows, list) and not rows:
        if empty_ok:
            return np.zeros((0, 3))
        raise _odd(path, field, "no poses")
    try:
        a = np.asarray(rows, np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.ndim != 2 or a.shape[1] != 3:
        raise _odd(path, field, "not rows of (x mm, y mm, yaw mrad)")
    bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
    if len(bad):
        raise _odd(path, field, f"NaN or infinite pose at row {int(bad[0])}: {rows[bad[0]]}")
    return a


@dataclass(frozen=True)
class EpisodePath:
    """One recorded episode of a robot run as the robot drove it: ``poses`` (n, 4: t s, x m, y m,
    yaw rad at 10 Hz from t = 0), the ``contacts`` (k, 3: tick, x m, y m), the tick each
    recognition's picture was taken (``pictures``), and when each event of a step happened."""

    run: RobotRun
    steps: list[tuple[int, int, int]]  # (state, action, flags) of each executed step
    seen: list[dict]  # each recognition's step and action, in order
    poses: np.ndarray
    contacts: np.ndarray
    pictures: np.ndarray
    contact_tick: dict[int, int]  # step -> tick of its collision
    decided: dict[int, int]  # step -> tick of its last picture
    starts: dict[int, int]  # step -> the tick it begins at

    @property
    def seconds(self) -> float:
        """How long the episode took: the next episode of a whole run's replay starts then."""
        return len(self.poses) / CONTROL_HZ

    def moment(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """The simulated second of an event of step ``t``: recognition number ``picture``'s when its
        picture was taken, a collision's (``contact``) at the contact, else when the step decided
        (its last picture) or began, the last step's at the path's end."""
        if picture is not None:
            tick = int(self.pictures[picture])
        elif contact and t in self.contact_tick:
            tick = self.contact_tick[t]
        elif t in self.decided:
            tick = self.decided[t]
        elif t >= len(self.steps) - 1:
            tick = len(self.poses) - 1
        else:
            tick = self.start_tick(t)
        return float(self.poses[min(tick, len(self.poses) - 1), 0])

    def start_tick(self, t: int) -> int:
        """The tick step ``t`` begins at (``episode_path``'s ``starts``)."""
        return self.starts[t]


@dataclass(frozen=True)
class RobotRun:
    """What a robot cell's records say of one run, checked (:func:`robot_run`): the motion table
    (``info.robot``), the cell size (m), the maze and the run's obstacles in ``layout.obstacles``
    order; ``file``: the record file, for errors."""

    table: dict
    cell: float
    layout: Layout
    obstacles: list[dict]
    file: Path

    half_sizes = HALF_SIZES
    camera = Camera()

    @property
    def placement(self) -> Placement:
        return Placement(
            np.array([o["physical"] for o in self.obstacles], np.int16),
            np.array([o["orientation"] for o in self.obstacles], np.int8),
        )

    def centres(self, cells) -> np.ndarray:
        """World (x, y) of cell centres (:func:`pipeline.robot.world.centre_of`)."""
        w, h = self.layout.width, self.layout.height
        return np.array([centre_of(c, w, h, self.cell) for c in cells]).reshape(-1, 2)

    def headings(self, actions) -> np.ndarray:
        """The world heading (rad, counter-clockwise from +x) of grid actions."""
        return np.array(HEADINGS)[np.asarray(actions, np.int64)]

    def scene(self):
        """The run's MuJoCo world, compiled and forwarded: ``(model, data)``."""
        spec, _ = build_world(self.layout, self.placement, self.cell)
        model = spec.compile()
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        return model, data

    def check(self, steps, recognitions) -> None:
        """The run's ``steps`` frame holds moves of the maze, and every row of its
        ``recognitions`` frame relation scores (every recogniser on the robot records those of its
        live pictures)."""
        n = self.layout.n_cells
        odd = steps[~steps.state.between(0, n - 1) | ~steps.action.between(0, len(HEADINGS) - 1)]
        if len(odd):
            r = odd.iloc[0]
            raise _odd(
                self.file,
                "steps",
                f"episode {int(r.episode)} step {int(r.step)}: cell {int(r.state)}, action "
                f"{int(r.action)} is not a move of the {n}-cell maze",
            )
        scores = [c for c in recognitions.columns if c.startswith("score_")]
        none = (
            recognitions[scores].isna().all(axis=1).to_numpy()
            if scores
            else np.ones(len(recognitions), bool)
        )
        if none.any():
            r = recognitions[none].iloc[0]
            raise _odd(
                self.file,
                "recognitions.scores",
                f"the recognition at run {int(r.run)} episode {int(r.episode)} step "
                f"{int(r.step)} has no relation scores (every recogniser on the robot records the "
                "scores of its live pictures)",
            )

    def path(self, steps, seen) -> dict:
        """The path of ``steps`` (state, action, flags) with the recognitions ``seen`` (step,
        action): :func:`pipeline.robot.motion.episode_path` with this run's table and maze."""
        return episode_path(self.table, self.layout, self.obstacles, steps, seen)

    def episode(self, e: int, steps, recognitions) -> EpisodePath:
        """Episode ``e`` from its rows of the ``steps`` and ``recognitions`` frames; its path meets
        an obstacle on every step flagged a collision, and takes a picture for every recognition."""
        moves = [
            (int(s), int(a), int(f)) for s, a, f in zip(steps.state, steps.action, steps["flags"])
        ]
        seen = [{"step": int(r.step), "action": int(r.action)} for r in recognitions.itertuples()]
        path = self.path(moves, seen)
        collided = [t for t, (_, _, f) in enumerate(moves) if f & S.FLAG_COLLIDED]
        if len(collided) != len(path["contacts"]):
            raise _odd(
                self.file,
                "steps.flags",
                f"episode {e} flags {len(collided)} collisions, but its moves meet an obstacle "
                f"{len(path['contacts'])} times",
            )
        if len(path["pictures"]) != len(seen):
            raise _odd(
                self.file,
                "recognitions.step",
                f"episode {e} has {len(seen)} recognitions, "
                f"{len(seen) - len(path['pictures'])} of them after its last step",
            )
        return EpisodePath(
            self,
            moves,
            seen,
            path["poses"],
            path["contacts"],
            path["pictures"],
            contact_tick={t: int(c[0]) for t, c in zip(collided, path["contacts"])},
            decided={r["step"]: int(k) for r, k in zip(seen, path["pictures"])},
            starts={t: int(k) for t, k in enumerate(path["starts"])},
        )


def robot_run(meta: FileMeta, run: int) -> RobotRun:
    """Run ``run`` of the robot record file ``meta``: its config's ``robot.cell`` (within
    :data:`pipeline.robot.limits.CELL_RANGE`), the motion table ``info.robot`` (simulated for that
    cell at 10 Hz: every turn and every drive the run's obstacles can need, with finite poses), the
    maze and the run's placement (one obstacle on each obstacle cell of the maze)."""
    path, table = meta.path, meta.info.get("robot")  # the info metadata's key robot
    if not isinstance(table, dict):
        raise _odd(
            path,
            "info.robot",
            ("no motion table" if table is None else f"{type(table).__name__}, not a motion table")
            + ", so the robot's path cannot be drawn (a robot cell's records keep it; run the "
            "cell again with the trials stage)",
        )
    robot = (meta.config if isinstance(meta.config, dict) else {}).get("robot")
    if not isinstance(robot, dict) or "cell" not in robot:
        raise _odd(path, "config robot.cell", "missing: the robot's cell size (m) builds its world")
    cell = _number(path, "config robot.cell", robot["cell"])
    timestep = _number(path, "info.robot.timestep", table.get("timestep"))
    try:
        check_settings(cell, timestep)
    except ValueError as exc:
        key = "config robot.cell" if str(exc).startswith("cell=") else "info.robot.timestep"
        raise _odd(path, key, str(exc)) from None
    simulated = _number(path, "info.robot.cell", table.get("cell"))
    if abs(simulated - cell) > 1e-9:
        raise _odd(
            path,
            "info.robot.cell",
            f"the motion table was simulated for {simulated} m cells, robot.cell is {cell} m",
        )
    hz = _number(path, "info.robot.control_hz", table.get("control_hz"))
    if hz != CONTROL_HZ:
        raise _odd(
            path, "info.robot.control_hz", f"{hz:g}: the robot's poses are at {CONTROL_HZ} Hz"
        )
    try:
        layout = parse_layout("\n".join(meta.maze["layout"]), f"{path}: maze metadata")
    except MazeError as exc:
        raise RobotRecordError(str(exc)) from None
    obstacles = _placement(meta, run, layout)
    _check_table(path, table, obstacles)
    return RobotRun(table, cell, layout, obstacles, path)


def _placement(meta: FileMeta, run: int, layout: Layout) -> list[dict]:
    """Run ``run``'s recorded obstacles, one on each of the maze's obstacle cells, in its order."""
    path, key = meta.path, f"obstacles (run {run})"
    recorded = meta.obstacles.get(run)
    if not isinstance(recorded, list):
        raise _odd(path, "obstacles", f"no placement of run {run}")
    by_cell = {}
    for o in recorded:
        if not isinstance(o, dict) or not all(
            isinstance(o.get(k), int) and not isinstance(o.get(k), bool) for k in OBSTACLE_KEYS
        ):
            raise _odd(path, key, f"{o!r}: an obstacle is integers {', '.join(OBSTACLE_KEYS)}")
        if not 0 <= o["physical"] < N_PHYSICAL_OBSTACLES or not 0 <= o["orientation"] < 4:
            raise _odd(
                path,
                key,
                f"{o!r}: physical must lie in 0-{N_PHYSICAL_OBSTACLES - 1}, orientation in 0-3",
            )
        if o["category"] != o["physical"] // INSTANCES_PER_CATEGORY:
            raise _odd(path, key, f"{o!r}: category is not that of the physical obstacle")
        by_cell[o["cell"]] = o
    if sorted(by_cell) != sorted(layout.obstacles) or len(recorded) != len(by_cell):
        raise _odd(
            path,
            key,
            f"obstacles on cells {sorted(o['cell'] for o in recorded)}, the maze's obstacle "
            f"cells are {sorted(layout.obstacles)}",
        )
    return [by_cell[c] for c in layout.obstacles]


def _check_table(path: Path, table: dict, obstacles: list[dict]) -> None:
    """Every turn of the motion table, and every drive the run's obstacles can need (any
    approach), has finite poses; an obstacle's drive its stop tick and contact point."""
    turns = table.get("turns")
    if not isinstance(turns, list) or len(turns) != 4:
        raise _odd(path, "info.robot.turns", "expected the poses of 4 turns (0-3 quarter turns)")
    for k, rows in enumerate(turns):
        _poses(path, f"info.robot.turns[{k}]", rows, empty_ok=True)
    drives = table.get("drives")
    if not isinstance(drives, dict):
        raise _odd(path, "info.robot.drives", "missing: the drives to a free or occupied neighbour")
    keys = {drive_key(o["physical"], q) for o in obstacles for q in range(4)}
    for key in [drive_key(None), *sorted(keys)]:
        name, drive = f"info.robot.drives.{key}", drives.get(key)
        if not isinstance(drive, dict):
            raise _odd(path, name, "missing: a drive the run's obstacles need")
        rows = _poses(path, f"{name}.poses", drive.get("poses"))
        stopped = drive.get("stopped")
        if (
            isinstance(stopped, bool)
            or not isinstance(stopped, int)
            or not 1 <= stopped <= len(rows)
        ):
            raise _odd(path, f"{name}.stopped", f"{stopped!r}: not a tick of its {len(rows)} poses")
        if key != drive_key(None):
            contact = drive.get("contact")
            if not isinstance(contact, list) or len(contact) < 2:
                raise _odd(path, f"{name}.contact", f"{contact!r}: not a point (x, y, z mm)")
            for v in contact:
                _number(path, f"{name}.contact", v)
