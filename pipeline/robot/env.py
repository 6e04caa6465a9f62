"""The maze navigation task with the camera robot in MuJoCo, one step at a time (Gymnasium).

SafeNavigation3DEnv
===================

:class:`pipeline.rl.gym_env.SafeNavigationEnv` in the robot's world
(:class:`~pipeline.robot.live_world.RobotWorld`): the same observation (the robot's cell), actions
(0 N, 1 E, 2 S, 3 W), rewards, A_d, decision rule (``rule``, ``threshold``) and self-recovery, with
the same code (``rules.apply_action``). What the robot world changes:

* the pictures: a method that reasons with pictures is asked about the **live picture** the robot's
  camera takes from the cell's centre facing the obstacle (any recogniser by name:
  :mod:`.live`), not about a pre-rendered query picture;
* the motion: each move is the robot's, under physics (the motion table, :mod:`.motion`): a turn
  in place, a drive, a contact with an obstacle's box and the drive back (self-recovery).

``info`` adds to the grid's: ``cost`` (1.0 on a collision, as Safety-Gymnasium), ``camera`` (the
live picture of the step, or None), ``scores`` (its scores, or None), ``contact`` (the world point
of the collision, or None), ``sim_time`` (simulated seconds of the step) and ``poses`` (rows t, x,
y, yaw at 10 Hz; t from the episode's start). ``render()`` (``rgb_array``) is the maze from above
and behind the robot, drawn by MuJoCo.

Arguments: those of ``SafeNavigationEnv`` but ``tile_size`` and ``world``, and the robot's ``cell``
(m, 0.5-2) and ``timestep`` (MuJoCo's step, s; 0.001-0.05 dividing the 0.1 s control tick).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.rules import Rule
from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP
from pipeline.robot.live import live
from pipeline.robot.live_world import RobotSettings, RobotWorld
from pipeline.robot.motion import PathBuilder
from pipeline.robot.sim import RobotSim
from pipeline.world.maze import Layout, load_layout


class SafeNavigation3DEnv(SafeNavigationEnv):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        maze: str | Layout = "5x5",
        method: str | MethodSpec = "shield",
        recogniser=None,
        run: int = 0,
        render_mode: str | None = None,
        cell: float = DEFAULT_CELL,
        timestep: float = DEFAULT_TIMESTEP,
        rule: str | Rule = Rule.paper,
        threshold: float = 0.5,
    ):
        layout = maze if isinstance(maze, Layout) else load_layout(maze)
        spec = method if isinstance(method, MethodSpec) else get_method(method)
        self.settings = RobotSettings(float(cell), float(timestep))
        world = RobotWorld(layout, self.settings, live_pictures=spec.uses_recogniser)
        if recogniser is not None and spec.uses_recogniser:
            recogniser = live(recogniser, world)
        self.motions = world.describe()
        self._sim: RobotSim | None = None
        super().__init__(
            layout,
            spec,
            recogniser,
            run=run,
            render_mode=render_mode,
            rule=rule,
            threshold=threshold,
            world=world,
        )

    def _new_run(self, seed: int) -> None:
        super()._new_run(seed)
        if self._sim is not None:
            self._sim.close()
            self._sim = None
        self._obstacles = self.world.placement.as_records(self.layout.obstacles)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        state, info = super().reset(seed=seed, options=options)
        self._path = PathBuilder(self.motions, self.layout, self._obstacles)
        extra = dict(camera=None, scores=None, contact=None, sim_time=0.0, cost=0.0)
        return state, {**info, **extra, "poses": self._path.poses().tolist()}

    def step(self, action):
        s, since, contacts = self.state, self._path.ticks, len(self._path.contacts)
        state, reward, terminated, truncated, info = super().step(action)
        camera = scores = None
        if info["picture"] >= 0:
            self._path.look(s, int(action))
            camera = self.world_model.image(info["picture"])
            scores = np.asarray(self.recogniser.scores(self.run_id, [info["picture"]]))[0]
        if not info["prevented"]:
            self._path.move(s, int(action), info["flags"])
        hit = self._path.contacts[contacts:]
        contact = tuple(float(v) for v in hit[0][1:]) if hit else None
        info.update(
            camera=camera,
            scores=None if scores is None else scores.tolist(),
            contact=contact,
            sim_time=(self._path.ticks - since) / 10.0,
            poses=self._path.poses(since).tolist(),
            cost=float(info["collided"]),
        )
        return state, reward, terminated, truncated, info

    def render(self):
        """``rgb_array``: the maze from above and behind the robot (480 x 640), drawn by MuJoCo."""
        if self.render_mode is None:
            return super().render()
        if self._sim is None:
            self._sim = RobotSim(
                self.layout, self.world.placement, self.settings.cell, self.settings.timestep
            )
        _, x, y, yaw = self._path.poses()[-1]
        self._sim.put(x, y, yaw)
        return self._sim.overview()

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None
