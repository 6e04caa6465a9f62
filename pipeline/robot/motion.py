"""The robot's transition under physics, as a table: every way a grid move can go, simulated once
in MuJoCo from a settled pose (paper section 5: decisions stay on the grid; the robot re-localises
on each cell centre).

A move from a cell centre is a turn in place to the move's heading, then a drive toward the
neighbour: free, or into an obstacle's box (a contact: the robot stops and, with self-recovery,
drives back). From a settled pose on a centre, MuJoCo is deterministic, and what a move meets lies
in the target cell alone (an obstacle's box stays within 0.45 of its cell; the robot drives along
the centre line), so a move is a pure function of

* the turn: the heading before the move relative to the move's, in quarter turns (0-3), and
* the drive: a free neighbour, or the obstacle there (its physical object and its orientation
  relative to the approach), with or without self-recovery.

:func:`motion_table` simulates each of them once, in the move's own frame (the start centre at the
origin, facing +x), and keeps the poses at the controller's 10 Hz in millimetres and milliradians.
The runner needs none of it (a move's outcome is the grid's: a free neighbour is reached, an
obstacle's box is always hit, which the table checks); the records keep the table once per file
(``info.robot``), and :func:`episode_path` expands any recorded episode back into the robot's poses,
contacts and the moments it took pictures. Rounding to millimetres keeps the recorded table the same
bytes on CPUs whose floating point differs in the last bits (issue 38).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from pipeline.records.schema import FLAG_COLLIDED, FLAG_RECOVERED
from pipeline.robot.sim import CONTROL_HZ, HEADINGS, RobotSim, wrap
from pipeline.robot.world import centre_of
from pipeline.world.layout import MOVES, parse_layout
from pipeline.world.pictures import N_PHYSICAL_OBSTACLES
from pipeline.world.placement import Placement

#: A grid action's heading in quarter turns counter-clockwise from +x (east): 0 N, 1 E, 2 S, 3 W.
QUARTERS = (1, 0, -1, 2)
#: The canonical worlds: the robot on the centre cell, its +x (east) neighbour free or an obstacle.
FREE_WORLD = parse_layout("S..\n...\n..G", "robot motion table (free)")
OBSTACLE_WORLD = parse_layout("S..\n..X\n..G", "robot motion table (obstacle)")
CENTRE, EAST = 4, 1


def _action_of_quarter(q: int) -> int:
    return QUARTERS.index(((q + 1) % 4) - 1)


def relative_orientation(orientation: int, action: int) -> int:
    """An obstacle's orientation (quarter turns clockwise) as seen approaching it with ``action``:
    in the move's frame (facing +x) it is turned by the action's heading."""
    return (int(orientation) + QUARTERS[action]) % 4


def drive_key(physical: int | None, orientation: int = 0) -> str:
    """The table's key of a drive: ``free``, or ``p<physical>_o<orientation in the move's frame>``."""
    return "free" if physical is None else f"p{int(physical)}_o{int(orientation)}"


def _ints(poses) -> list[list[int]]:
    return [[round(x * 1000), round(y * 1000), round(wrap(yaw) * 1000)] for x, y, yaw in poses]


@lru_cache(maxsize=8)
def motion_table(cell: float, timestep: float) -> dict:
    """Every turn and drive of the robot world with ``cell`` m cells and a ``timestep`` s physics
    step (JSON-able; units mm and mrad, the move's frame). ``turns[k]``: the poses of a turn by
    ``k`` quarter turns counter-clockwise; ``drives[key]`` (:func:`drive_key`): ``poses`` of the
    drive with self-recovery, ``stopped`` (ticks up to the stop after the contact; the drive without
    self-recovery ends there) and the first ``contact`` point."""
    empty = RobotSim(
        FREE_WORLD, Placement(np.zeros(0, np.int16), np.zeros(0, np.int8)), cell, timestep
    )
    turns = []
    for k in range(4):
        empty.place(CENTRE, EAST)
        turns.append(_ints(empty.turn(_action_of_quarter(k))))
    empty.place(CENTRE, EAST)
    poses, hit, _ = empty.drive(EAST, recover=True)
    if hit is not None:
        raise RuntimeError(f"cell={cell}: the robot touched {hit[1]} driving to a free neighbour")
    drives = {drive_key(None): {"poses": _ints(poses), "stopped": len(poses), "contact": None}}
    empty.close()
    for physical in range(N_PHYSICAL_OBSTACLES):
        for orientation in range(4):
            placement = Placement(np.array([physical], np.int16), np.array([orientation], np.int8))
            sim = RobotSim(OBSTACLE_WORLD, placement, cell, timestep)
            sim.place(CENTRE, EAST)
            poses, hit, stopped = sim.drive(EAST, recover=True)
            if hit is None or not hit[1].startswith("obstacle"):
                raise RuntimeError(
                    f"cell={cell}: driving into obstacle {physical} (orientation {orientation}) "
                    f"the robot met {hit and hit[1]}, not the obstacle's box"
                )
            point = [round(v * 1000) for v in hit[0]]
            drives[drive_key(physical, orientation)] = {
                "poses": _ints(poses),
                "stopped": stopped,
                "contact": point,
            }
            sim.close()
    return {
        "cell": float(cell),
        "timestep": float(timestep),
        "control_hz": CONTROL_HZ,
        "units": "mm, mrad; the move's frame: its start centre at the origin, facing +x",
        "turns": turns,
        "drives": drives,
    }


def _to_world(rows, centre, heading: float) -> np.ndarray:
    """(n, 3) poses of the move's frame (mm, mrad) in the world: metres and radians."""
    if not len(rows):
        return np.zeros((0, 3))
    a = np.asarray(rows, np.float64) / 1000.0
    c, s = np.cos(heading), np.sin(heading)
    x = centre[0] + c * a[:, 0] - s * a[:, 1]
    y = centre[1] + s * a[:, 0] + c * a[:, 1]
    yaw = (a[:, 2] + heading + np.pi) % (2 * np.pi) - np.pi
    return np.stack([x, y, yaw], axis=1)


class PathBuilder:
    """The robot's path through an episode, move by move, from the motion ``table`` (as recorded):
    every episode starts on the start cell facing north. ``obstacles``: the run's placement as
    recorded (``cell``, ``physical``, ``orientation``). Poses are (x m, y m, yaw rad) at 10 Hz."""

    def __init__(self, table: dict, layout, obstacles: list[dict]):
        self.table, self.layout = table, layout
        self.size = float(table["cell"])
        self.by_cell = {int(o["cell"]): o for o in obstacles}
        self.heading = 0
        self.segments = [self._world([[0, 0, 0]], layout.start, HEADINGS[0])]
        self.ticks = 1
        self.contacts: list[tuple[float, float, float]] = []
        self.pictures: list[int] = []

    def _world(self, rows, cell: int, heading: float) -> np.ndarray:
        w, h = self.layout.width, self.layout.height
        return _to_world(rows, centre_of(cell, w, h, self.size), heading)

    def _add(self, poses: np.ndarray) -> None:
        self.segments.append(poses)
        self.ticks += len(poses)

    def turn(self, cell: int, action: int) -> None:
        """Turn in place on ``cell``'s centre to ``action``'s heading."""
        rel = (QUARTERS[action] - QUARTERS[self.heading]) % 4
        self._add(self._world(self.table["turns"][rel], cell, HEADINGS[self.heading]))
        self.heading = action

    def look(self, cell: int, action: int) -> None:
        """Turn toward ``action``'s neighbour and take a picture (at the last tick of the turn)."""
        self.turn(cell, action)
        self.pictures.append(self.ticks - 1)

    def move(self, cell: int, action: int, flags: int) -> None:
        """One executed move (``flags``: the step's ``StepFlag`` bits, as recorded): off the grid
        the robot stays put (it knows the maze's size); else it turns and drives, into the
        obstacle there when there is one (a contact; back to ``cell`` with self-recovery)."""
        w, h = self.layout.width, self.layout.height
        row, col = divmod(int(cell), w)
        dr, dc = MOVES[action]
        if not (0 <= row + dr < h and 0 <= col + dc < w):
            return
        self.turn(cell, action)
        target = self.by_cell.get(int(cell) + dr * w + dc)
        if target is None:
            self._add(self._world(self.table["drives"]["free"]["poses"], cell, HEADINGS[action]))
            return
        key = drive_key(target["physical"], relative_orientation(target["orientation"], action))
        drive = self.table["drives"][key]
        recovered = bool(flags & FLAG_RECOVERED) or not flags & FLAG_COLLIDED
        rows = drive["poses"] if recovered else drive["poses"][: drive["stopped"]]
        point = self._world([[*drive["contact"][:2], 0]], cell, HEADINGS[action])[0]
        self.contacts.append((self.ticks + drive["stopped"] - 2, point[0], point[1]))
        self._add(self._world(rows, cell, HEADINGS[action]))

    def poses(self, since: int = 0) -> np.ndarray:
        """(n, 4) rows t (s), x, y, yaw of the ticks from tick ``since`` on."""
        poses = np.concatenate(self.segments)[since:]
        t = np.arange(since, since + len(poses), dtype=np.float64) / CONTROL_HZ
        return np.column_stack([t, poses])


def episode_path(table: dict, layout, obstacles: list[dict], steps, recognitions) -> dict:
    """The robot's path through one recorded episode (:class:`PathBuilder`).

    ``steps``: rows ``(state, action, flags)`` (the executed moves, in order); ``recognitions``:
    rows with ``step`` and ``action`` (each picture, taken after turning toward it, before step
    ``step`` moves). Returns ``poses`` (n, 4: t s, x m, y m, yaw rad at 10 Hz, the start pose at
    t = 0), ``contacts`` (tick, x, y), ``pictures`` (the tick of each recognition) and ``starts``
    (the tick each step begins at).
    """
    path = PathBuilder(table, layout, obstacles)
    looks = [(int(r["step"]), int(r["action"])) for r in recognitions]
    k, starts = 0, []
    for t, (s, a, flags) in enumerate(steps):
        starts.append(path.ticks - 1)
        while k < len(looks) and looks[k][0] == t:
            path.look(int(s), looks[k][1])
            k += 1
        path.move(int(s), int(a), int(flags))
    return {
        "poses": path.poses(),
        "contacts": np.array(path.contacts, np.float64).reshape(-1, 3),
        "pictures": np.array(path.pictures, np.int64),
        "starts": np.array(starts, np.int64),
    }
