"""The robot under physics at one grid cell (issue 30; the paper's discretisation, section 5:
decisions stay on the grid).

:class:`RobotSim` holds one compiled world (:func:`pipeline.robot.world.build_world`). From a
settled pose on a cell centre (:meth:`RobotSim.place`) it turns in place to a move's heading
(:meth:`RobotSim.turn`), drives toward the next centre (:meth:`RobotSim.drive`) with wheel speeds
inside the Burger's limits (:func:`wheel_limited`), reads its range sensor and takes pictures. A
collision is a MuJoCo contact between the robot's body and an obstacle or a wall, detected after
every control tick; the robot then stops and self-recovery drives it backwards to the previous
cell's centre (section 3.3).

The control loop runs at :data:`CONTROL_HZ` (10 Hz, the rate of the recorded poses); each tick is
one ``mj_step(model, data, nstep=k)`` call of ``k = 1 / (CONTROL_HZ * timestep)`` physics steps.
Sensors (36 rangefinders) are disabled while driving and computed only when the range sensor is
read (:meth:`RobotSim.scan`).
"""

from __future__ import annotations

import numpy as np

from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP, check_settings
from pipeline.robot.model import (
    CAMERA,
    GEOM,
    LDS_RANGE,
    MAX_TURN,
    MAX_WHEEL,
    WHEEL_RADIUS,
    WHEEL_SEPARATION,
    ray_angles,
)
from pipeline.robot.world import WorldMap, build_world
from pipeline.world.layout import MOVES, Layout
from pipeline.world.placement import Placement
from pipeline.world.renderer_env import make_renderer, mujoco

CONTROL_HZ = 10
#: Heading (radians, counter-clockwise from +x) of each grid action: 0 N, 1 E, 2 S, 3 W.
HEADINGS = (np.pi / 2, 0.0, -np.pi / 2, np.pi)
#: A move ends within this distance (m) of the target centre, and this heading error (rad).
ARRIVE_TOLERANCE = 0.005
TURN_TOLERANCE = 0.005
MAX_TICKS = 400  # per phase: 40 simulated seconds, far above any legal move


def wrap(angle: float) -> float:
    """``angle`` in (-pi, pi]."""
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def wheel_limited(v: float, omega: float) -> tuple[float, float]:
    """``(v, omega)`` after limiting the two wheel speeds to the Burger's (both scaled by the same
    factor, so the path's curvature is kept) and omega to its 2.84 rad/s."""
    omega = max(-MAX_TURN, min(MAX_TURN, float(omega)))
    left = (v - omega * WHEEL_SEPARATION / 2) / WHEEL_RADIUS
    right = (v + omega * WHEEL_SEPARATION / 2) / WHEEL_RADIUS
    scale = max(1.0, abs(left) / MAX_WHEEL, abs(right) / MAX_WHEEL)
    left, right = left / scale, right / scale
    return (
        WHEEL_RADIUS * (left + right) / 2,
        WHEEL_RADIUS * (right - left) / WHEEL_SEPARATION,
    )


class RobotSim:
    """The robot in one run's maze. ``timestep`` is MuJoCo's (s); the controller ticks at
    :data:`CONTROL_HZ`."""

    def __init__(
        self,
        layout: Layout,
        placement: Placement,
        cell: float = DEFAULT_CELL,
        timestep: float = DEFAULT_TIMESTEP,
        render_seed: int = 0,
    ):
        check_settings(cell, timestep)
        substeps = round(1.0 / (CONTROL_HZ * timestep))
        spec, self.map = build_world(layout, placement, cell, render_seed)
        spec.option.timestep = float(timestep)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.substeps = substeps
        self.dt = 1.0 / CONTROL_HZ
        m = self.model
        self._robot_geom = m.geom(GEOM).id
        self._obstacle_geoms = {m.geom(g).id: g for g in self.map.obstacle_geoms}
        self._wall_geoms = {m.geom(f"wall{k}").id: f"wall{k}" for k in range(4)}
        self._sensors_off()
        self.physics_steps = 0
        self.camera_id = m.camera(CAMERA).id
        self._renderer = self._overview = None
        self._vopt = mujoco.MjvOption()  # pictures without the rangefinders' rays drawn
        self._vopt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0

    # ----------------------------------------------------------------- state

    @property
    def world(self) -> WorldMap:
        return self.map

    def _sensors_off(self) -> None:
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)

    def place(self, cell: int, action: int = 0) -> None:
        """The robot at rest exactly on ``cell``'s centre, facing ``action``'s heading: the settled
        pose every grid move starts from (the robot re-localises at each centre)."""
        x, y = self.map.centre(cell)
        self.put(x, y, HEADINGS[action])

    def put(self, x: float, y: float, yaw: float) -> None:
        """The robot at rest at ``(x, y)`` facing ``yaw`` (radians)."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = [x, y, yaw]
        mujoco.mj_forward(self.model, self.data)

    def pose(self) -> tuple[float, float, float]:
        x, y, yaw = self.data.qpos[:3]
        return float(x), float(y), wrap(float(yaw))

    def scan(self) -> np.ndarray:
        """The range sensor: one distance per ray (:func:`model.ray_angles`, robot frame);
        ``inf`` where nothing is within the LDS-01's 0.12-3.5 m."""
        m, d = self.model, self.data
        m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        mujoco.mj_forward(m, d)
        r = d.sensordata[: len(ray_angles())].copy()
        self._sensors_off()
        r[(r < LDS_RANGE[0]) | (r > LDS_RANGE[1])] = np.inf
        return r

    def occupied(self, action: int, scan: np.ndarray | None = None) -> bool:
        """Whether the range sensor finds something in the neighbouring cell toward ``action``
        (a move that stays on the grid): the ray nearest that direction reads less than one cell.
        An obstacle's box always reaches in front of its cell's centre; a box two cells away never
        comes nearer than 1.55 cells (its half-width is capped at 0.45 of a cell); walls lie only
        off the grid."""
        r = self.scan() if scan is None else scan
        yaw = self.pose()[2]
        rel = np.array([wrap(HEADINGS[action] - yaw - a) for a in ray_angles()])
        k = int(np.argmin(np.abs(rel)))
        return bool(r[k] < self.map.cell)

    def inside(self, cell: int, action: int) -> bool:
        """Whether ``action`` from ``cell`` stays on the grid (the robot knows the maze's size)."""
        w, h = self.map.layout.width, self.map.layout.height
        row, col = divmod(int(cell), w)
        dr, dc = MOVES[action]
        return 0 <= row + dr < h and 0 <= col + dc < w

    # ----------------------------------------------------------------- control

    def _contact(self) -> tuple[tuple[float, float, float], str] | None:
        d = self.data
        for i in range(d.ncon):
            g1, g2 = int(d.contact.geom1[i]), int(d.contact.geom2[i])
            if self._robot_geom not in (g1, g2):
                continue
            other = g2 if g1 == self._robot_geom else g1
            name = self._obstacle_geoms.get(other) or self._wall_geoms.get(other)
            if name is not None:
                return tuple(float(v) for v in d.contact.pos[i]), name
        return None

    def _tick(self, v: float, omega: float, poses: list) -> None:
        v, omega = wheel_limited(v, omega)
        yaw = self.data.qpos[2]
        self.data.ctrl[:] = [v * np.cos(yaw), v * np.sin(yaw), omega]
        mujoco.mj_step(self.model, self.data, nstep=self.substeps)
        self.physics_steps += self.substeps
        poses.append(self.pose())

    def _stop(self, poses: list) -> None:
        self._tick(0.0, 0.0, poses)

    def _turn(self, heading: float, poses: list) -> None:
        for _ in range(MAX_TICKS):
            err = wrap(heading - self.data.qpos[2])
            if abs(err) < TURN_TOLERANCE:
                return
            self._tick(0.0, err / self.dt, poses)
        raise RuntimeError(f"robot did not turn to {heading:.3f} rad in {MAX_TICKS} ticks")

    def _drive(self, target: np.ndarray, poses: list, backwards: bool, watch: bool):
        """Drive to ``target`` (forwards, or backwards for self-recovery); returns the first
        contact when ``watch``, else None. Far from the target (over 5 cm) a heading error over
        0.2 rad is first turned away in place (a contact can twist the robot); near it the robot
        drives straight and stops when the distance left along its heading is under the arrival
        tolerance (a differential drive cannot move sideways)."""
        sign = -1.0 if backwards else 1.0
        for _ in range(MAX_TICKS):
            x, y, yaw = self.pose()
            delta = target - np.array([x, y])
            dist = float(np.hypot(*delta))
            heading = np.arctan2(delta[1], delta[0]) + (np.pi if backwards else 0.0)
            err = wrap(heading - yaw)
            along = dist * np.cos(err)
            if dist < ARRIVE_TOLERANCE or (dist <= 0.05 and along < ARRIVE_TOLERANCE):
                return None
            if dist > 0.05 and abs(err) > 0.2:
                self._tick(0.0, err / self.dt, poses)
            else:
                omega = err / self.dt if dist > 0.05 else 0.0
                self._tick(sign * max(along, 0.0) / self.dt, omega, poses)
            if watch:
                hit = self._contact()
                if hit is not None:
                    return hit
        raise RuntimeError(f"robot did not reach {target} in {MAX_TICKS} ticks")

    def turn(self, action: int) -> list:
        """Turn in place to ``action``'s heading; the poses (x, y, yaw) of its ticks."""
        poses: list = []
        self._turn(HEADINGS[action], poses)
        return poses

    def drive(self, action: int, recover: bool) -> tuple[list, tuple | None, int]:
        """Drive from the centre the robot stands on toward ``action``'s neighbour (already facing
        it). On a contact the robot stops and, with ``recover``, drives backwards to the centre it
        left (self-recovery). Returns the poses of the ticks, the first contact ``(point, what)``
        or None, and the number of ticks up to and including the stop after the contact."""
        poses: list = []
        start = self.map.centre(self.map.cell_at(self.pose()[:2]))
        dx, dy = np.cos(HEADINGS[action]), np.sin(HEADINGS[action])
        target = start + self.map.cell * np.array([dx, dy])
        hit = self._drive(target, poses, backwards=False, watch=True)
        self._stop(poses)
        stopped = len(poses)
        if hit is not None and recover:
            self._drive(start, poses, backwards=True, watch=False)
            self._stop(poses)
        return poses, hit, stopped

    def picture(self, size: int) -> np.ndarray:
        """The forward camera's picture (RGB uint8), the centre ``size`` x ``size`` square of its
        4:3 frame (62.2 x 48.8 degrees); one renderer per world, made on first use."""
        if self._renderer is None:
            width = round(size * 4 / 3)
            self._renderer = make_renderer(self.model, size, width)
        mujoco.mj_forward(self.model, self.data)
        self._renderer.update_scene(self.data, camera=self.camera_id, scene_option=self._vopt)
        frame = self._renderer.render()
        left = (frame.shape[1] - size) // 2
        return frame[:, left : left + size].copy()

    def overview(self, height: int = 480, width: int = 640) -> np.ndarray:
        """The maze from above and behind the robot (RGB uint8), for ``render_mode='rgb_array'``."""
        if self._overview is None:
            self._overview = make_renderer(self.model, height, width)
        x, y, yaw = self.pose()
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = [x, y, 0.2]
        cam.distance = 2.5 * self.map.cell
        cam.azimuth = float(np.rad2deg(yaw))
        cam.elevation = -50.0
        mujoco.mj_forward(self.model, self.data)
        self._overview.update_scene(self.data, camera=cam, scene_option=self._vopt)
        return self._overview.render().copy()

    def close(self) -> None:
        for r in (self._renderer, self._overview):
            if r is not None:
                r.close()
        self._renderer = self._overview = None
