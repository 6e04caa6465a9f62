"""The maze navigation task with the robot under physics (issue 30): the grid's decisions (paper
section 5: the world discretised into squares), MuJoCo's outcomes.

SafeNavigation3DEnv
===================

The same observation (the robot's cell), actions (0 N, 1 E, 2 S, 3 W), rewards and A_d as
:class:`pipeline.rl.gym_env.SafeNavigationEnv`; what changes is where the outcome of a move comes
from. At a cell centre the robot:

1. reads its range sensor (:meth:`RobotSim.occupied`): is the neighbour toward ``a`` occupied?
   (An off-grid move leaves the robot in place, as in the grid world; it knows the maze's size.)
2. if the method reasons with pictures and the neighbour is occupied: turns toward it, takes a
   picture with its own camera and asks the recogniser for the live picture's scores
   (:meth:`live_scores`). It treats the move as dangerous when the top score reaches
   ``threshold``: (s, a) joins A_d and the move is not executed (Algorithm 1, lines 4-10).
   The decision reads the scores only: a network's scores never read the layout's categories.
   (The grid's rule compares the prediction with the true category, which a robot cannot know; a
   model of recognition, which answers as the grid, stops exactly where the grid's rule would;
   docs/robot3d.md.)
3. otherwise drives (:meth:`RobotSim.move`). A collision is a MuJoCo contact with an obstacle's
   body; self-recovery drives the robot back to the previous cell centre.

The safety rules are ``rules.apply_action``'s, called with one-entry tables that encode what the
physics and the recogniser said (``_tables``), so the grid and the robot share one implementation.

``info`` adds to the grid's: ``cost`` (1.0 on a collision, as Safety-Gymnasium), ``camera`` (the
live picture, or None), ``scores``, ``contact`` (world point of the collision), ``sim_time``
(simulated seconds of this step) and ``poses`` (t, x, y, yaw at 10 Hz).

The recogniser is any of the grid's, wrapped by :func:`pipeline.robot.live.live`: a few-shot
network scores the live picture itself; a model of recognition (the oracle, ``fixed_accuracy``,
``paper_tables``) answers it as the grid answers the query picture of the same obstacle's side.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pipeline.rl.codes import Outcome, StepFlag
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import apply_action, empty_added, reasons_with_pictures
from pipeline.rl.runner import make_run_world
from pipeline.rl.structs import MethodParams
from pipeline.robot.live import LiveView, live
from pipeline.robot.sim import RobotSim
from pipeline.robot.world import DEFAULT_CELL
from pipeline.world.geometry import build_geometry
from pipeline.world.layout import MOVES
from pipeline.world.maze import Layout, load_layout

PICTURE_SIZE = 84  # the recognisers' input (the paper's 84 x 84)


class SafeNavigation3DEnv(gym.Env):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        maze: str | Layout = "5x5",
        method: str | MethodSpec = "shield",
        recogniser=None,
        run: int = 0,
        render_mode: str | None = None,
        cell: float = DEFAULT_CELL,
        timestep: float = 0.02,
        threshold: float = 0.5,
    ):
        self.layout = maze if isinstance(maze, Layout) else load_layout(maze)
        self.method = method if isinstance(method, MethodSpec) else get_method(method)
        self._params = MethodParams.of(self.method)
        self._sees = reasons_with_pictures(self._params.safety)
        if self._sees:
            if recogniser is None:
                raise ValueError(
                    f"method {self.method.name!r} reasons with pictures: pass a recogniser"
                )
            recogniser = live(recogniser)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r}: expected 'rgb_array' or None")
        if not 0.0 < threshold <= 1.0:
            raise ValueError(f"threshold={threshold}: must lie in (0, 1]")
        self.render_mode, self.recogniser, self.run_id = render_mode, recogniser, run
        self.cell, self.timestep, self.threshold = float(cell), float(timestep), float(threshold)
        self.geometry = build_geometry(self.layout)
        n = self.layout.n_cells
        self.observation_space = spaces.Discrete(n)
        self.action_space = spaces.Discrete(4)
        self._added = empty_added()
        self._obstacle = np.full((n, 4), -1, np.int32)  # one entry set per step (``_tables``)
        self._next = np.arange(n, dtype=np.int32)[:, None].repeat(4, axis=1)
        self._pictures = np.zeros((n, 4), np.int16)  # every pair sees "picture 0", the live one
        self._true = np.ones(max(len(self.layout.obstacles), 1), np.int8)
        self._predicted = np.zeros(1, np.int8)  # 1: the live picture was recognised
        self.sim: RobotSim | None = None
        self._new_run(0)

    def _new_run(self, seed: int) -> None:
        self.run_seed = seed
        self.world = make_run_world(self.geometry, seed, self.run_id)
        if self.sim is not None:
            self.sim.close()
        self.sim = RobotSim(self.layout, self.world.placement, self.cell, self.timestep)
        self.unsafe = np.zeros((self.layout.n_cells, 4), dtype=np.bool_)
        if self._sees:
            self.recogniser.start_run(self.run_id, run_seeds(seed, self.run_id).recogniser)
        self._place(self.layout.start)

    def _place(self, cell: int) -> None:
        self.state, self.t = int(cell), 0
        self.sim.reset(cell)

    def action_mask(self) -> np.ndarray:
        return (~self.unsafe[self.state]).astype(np.int8)

    def _info(self, **extra) -> dict:
        return {"action_mask": self.action_mask(), "step": self.t, **extra}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._new_run(int(seed))
        self._place(self.layout.start)
        return self.state, self._info(
            prevented=False, collided=False, cost=0.0, camera=None, scores=None, contact=None,
            sim_time=0.0, poses=[], flags=0, added=[], substituted=-1,
        )  # fmt: skip

    def _target(self, s: int, a: int) -> int:
        dr, dc = MOVES[a]
        return s + dr * self.layout.width + dc

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action {action!r} outside Discrete(4)")
        s, sim = self.state, self.sim
        sim_start, poses = sim.time, []
        camera = scores = contact = None
        recognised, view = False, None
        inside = sim.inside(s, a)
        if self._sees and inside and sim.occupied(a):
            poses += sim.face(a).poses
            camera = sim.picture(PICTURE_SIZE)
            view = LiveView(
                camera, self._truth_at(self._target(s, a)), int(self.world.pictures[s, a])
            )
            scores = np.asarray(self.recogniser.live_scores(self.run_id, view), float)
            recognised = bool(scores.max() >= self.threshold)
        o, s_next = -1, s
        if recognised:
            o = 0  # the rule needs an obstacle index; "recognised" is all it reads here
        elif inside:
            result = sim.move(s, a, recover=self._params.recovery and not self._params.constrained)
            poses += result.poses
            s_next = result.cell
            if result.collided:
                if not result.contact_geom.startswith("obstacle"):
                    raise RuntimeError(f"robot touched {result.contact_geom} on a grid move")
                o = int(result.contact_geom[len("obstacle") :].split("_")[0])
                contact = result.contact
        out, s2, reward, terminated, flags, _, n_added = self._apply(s, a, o, s_next, recognised)
        added = [tuple(int(x) for x in self._added[k]) for k in range(n_added)]
        extra = dict(
            camera=camera, scores=None if scores is None else scores.tolist(), contact=contact,
            sim_time=round(sim.time - sim_start, 6), poses=poses, added=added, substituted=-1,
        )  # fmt: skip
        if out == Outcome.prevented:
            return s, 0.0, False, False, self._info(prevented=True, collided=False, cost=0.0,
                                                    flags=0, **extra)  # fmt: skip
        collided = out == Outcome.collided
        if collided and self._params.dynamic and camera is not None:
            # self-recovery's reflection (section 3.3): the live picture joins the support set of
            # the category the robot collided with (the world tells it, as in the grid world)
            extra["substituted"] = self.recogniser.learn_from_live(self.run_id, view)
        if collided and terminated:
            s2 = s  # the episode ends where the robot stopped; the grid state stays the last cell
        self.t += 1
        self.state = int(s2)
        truncated = (not terminated) and self.t >= self.method.max_steps
        if truncated:
            flags |= StepFlag.truncated
        info = self._info(prevented=False, collided=collided, cost=float(collided),
                          flags=int(flags), **extra)  # fmt: skip
        return self.state, float(reward), bool(terminated), bool(truncated), info

    def _truth_at(self, cell: int) -> int:
        """Ground-truth category on ``cell`` (for models of recognition, the substitution and the
        records; a network's decision never reads it), or -1 for no obstacle."""
        obstacles = self.layout.obstacles
        return int(self.world.true_category[obstacles.index(cell)]) if cell in obstacles else -1

    def _apply(self, s: int, a: int, o: int, s_next: int, recognised: bool):
        """``rules.apply_action`` on tables holding only this step's outcome: obstacle ``o`` ahead
        (or -1), the cell reached ``s_next``, and whether the live picture was recognised."""
        self._obstacle[s, a], self._next[s, a] = o, s_next
        self._predicted[0] = 1 if recognised else 0
        g, p = self.geometry, self._params
        try:
            return apply_action(
                s, a, p.safety, p.recovery, p.constrained, self._next, self._obstacle,
                g.ssrl_pairs, self.layout.goal, self._pictures, self._true, self._predicted,
                self.unsafe, self._added,
            )  # fmt: skip
        finally:
            self._obstacle[s, a], self._next[s, a] = -1, s

    def render(self):
        """``rgb_array``: the maze from above and behind the robot (480 x 640)."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() without a render_mode: make the env with render_mode='rgb_array'"
            )
            return None
        return self.sim.overview()

    def close(self) -> None:
        if self.sim is not None:
            self.sim.close()
