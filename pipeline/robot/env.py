"""The maze navigation task with the camera robot in MuJoCo, one step at a time (Gymnasium).

SafeNavigation3DEnv
===================

:class:`pipeline.rl.gym_env.SafeNavigationEnv` in the robot's world
(:class:`~pipeline.robot.live_world.RobotWorld`): the same observation (the robot's cell; the
camera's picture by ``obs_type``, below), actions (0 N, 1 E, 2 S, 3 W), rewards, A_d, decision
rule (``rule``, ``threshold``) and self-recovery, with the same code (``rules.apply_action``). What
the robot world changes:

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

Observation (``obs_type``, one of :data:`OBS_TYPES`; Gymnasium's names, those of its
``AddRenderObservation`` wrapper):

* ``"state"`` (the default): the robot's cell, ``Discrete(height * width)``, as on the grid;
* ``"pixels"``: the camera's picture alone, ``Box(0, 255, (84, 84, 3), uint8)``, as the wrapper's
  ``render_only=True`` gives its frame;
* ``"state+pixels"``: ``Dict`` with the keys ``"state"`` and ``"pixels"``, as its ``render_only=False``.

Every ``reset`` and ``step`` has its picture, whether or not the step took a live picture: the robot
re-localises whenever it stands still (:mod:`.motion`), so its camera looks from the centre of the
observation's cell toward the robot's heading (north at the start; a move, a look at an obstacle or
a collision turns it), with the camera and crop of the live pictures. On a step that took a live
picture the pixels are that picture (``info["camera"]``); on the others, what the camera sees
ahead. A collision that ends the episode (no self-recovery) is seen from the cell the robot left,
the observation's cell. A run renders each (cell, heading) once.

Arguments: those of ``SafeNavigationEnv`` but ``tile_size`` and ``world``, the robot's ``cell``
(m, 0.5-2) and ``timestep`` (MuJoCo's step, s; 0.001-0.05 dividing the 0.1 s control tick), and
``obs_type``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.rules import Rule
from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP
from pipeline.robot.live import live
from pipeline.robot.live_world import PICTURE_SIZE, RobotSettings, RobotWorld
from pipeline.robot.motion import PathBuilder
from pipeline.robot.sim import RobotSim
from pipeline.robot.world import MAX_SEEN_OBSTACLES
from pipeline.world.maze import Layout, load_layout

#: The observations of ``obs_type`` (module docstring): Gymnasium's keys, alone or together.
OBS_TYPES = ("state", "pixels", "state+pixels")


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
        obs_type: str = "state",
    ):
        if not isinstance(obs_type, str) or obs_type not in OBS_TYPES:
            raise ValueError(f"obs_type={obs_type!r}: expected one of {', '.join(OBS_TYPES)}")
        layout = maze if isinstance(maze, Layout) else load_layout(maze)
        if obs_type != "state" and len(layout.obstacles) > MAX_SEEN_OBSTACLES:
            raise ValueError(
                f"obs_type={obs_type!r}: maze {layout.name} has {len(layout.obstacles):,} "
                f"obstacles; the robot's camera sees a maze of at most {MAX_SEEN_OBSTACLES:,}"
            )
        self.obs_type = obs_type
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
        pixels = spaces.Box(0, 255, (PICTURE_SIZE, PICTURE_SIZE, 3), np.uint8)
        by_type = {"state": self.observation_space, "pixels": pixels}
        by_type["state+pixels"] = spaces.Dict(by_type)
        self.observation_space = by_type[obs_type]

    def _new_run(self, seed: int) -> None:
        super()._new_run(seed)
        self.close()  # the new run's maze is built in MuJoCo on first use (_robot_sim)
        self._pictures: dict[tuple[int, int], np.ndarray] = {}  # (cell, heading) -> pixels
        self._obstacles = self.world.placement.as_records(self.layout.obstacles)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        state, info = super().reset(seed=seed, options=options)
        self._path = PathBuilder(self.motions, self.layout, self._obstacles)
        extra = dict(camera=None, scores=None, contact=None, sim_time=0.0, cost=0.0)
        return self._observation(state), {**info, **extra, "poses": self._path.poses().tolist()}

    def step(self, action):
        s, since, contacts = self.state, self._path.ticks, len(self._path.contacts)
        state, reward, terminated, truncated, info = super().step(action)
        camera = scores = None
        if info["picture"] >= 0:
            self._path.look(s, int(action))
            camera = self.world_model.image(info["picture"])
            scores = np.asarray(self.recogniser.scores(self.run_id, [info["picture"]]))[0].tolist()
        if not info["prevented"]:
            self._path.move(s, int(action), info["flags"])
        hit = self._path.contacts[contacts:]
        contact = tuple(float(v) for v in hit[0][1:]) if hit else None
        info.update(
            camera=camera,
            scores=scores,
            contact=contact,
            sim_time=(self._path.ticks - since) / 10.0,
            poses=self._path.poses(since).tolist(),
            cost=float(info["collided"]),
        )
        return self._observation(state), reward, terminated, truncated, info

    def _observation(self, state: int):
        """The observation of ``obs_type`` in ``state`` (module docstring)."""
        if self.obs_type == "state":
            return state
        parts = {"state": state, "pixels": self._camera(state)}
        return parts if self.obs_type == "state+pixels" else parts[self.obs_type]

    def _camera(self, cell: int) -> np.ndarray:
        """The forward camera's picture from the centre of ``cell``, facing the robot's heading
        (the pose it re-localises to; module docstring), rendered once a run (the maze stands
        still) and handed out as a copy."""
        key = (int(cell), self._path.heading)
        if key not in self._pictures:
            sim = self._robot_sim()
            sim.place(*key)
            self._pictures[key] = sim.picture(PICTURE_SIZE)
        return self._pictures[key].copy()

    def _robot_sim(self) -> RobotSim:
        """The run's maze in MuJoCo, built on first use (for pictures and ``render``)."""
        if self._sim is None:
            self._sim = RobotSim(
                self.layout, self.world.placement, self.settings.cell, self.settings.timestep
            )
        return self._sim

    def render(self):
        """``rgb_array``: the maze from above and behind the robot (480 x 640), drawn by MuJoCo."""
        if self.render_mode is None:
            return super().render()
        sim = self._robot_sim()
        _, x, y, yaw = self._path.poses()[-1]
        sim.put(x, y, yaw)
        return sim.overview()

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None
