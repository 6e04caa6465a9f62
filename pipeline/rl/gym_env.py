"""Gymnasium front door: the same rules as the batched runner, one step at a time.

SafeNavigationEnv
=================

Description
    A robot navigates a grid maze from ``S`` to ``G`` among obstacles (paper section 4.1). The
    environment carries the method's safety layer and self-recovery (``rules.apply_action``):
    the unsafe set A_d, the few-shot recogniser (if any) and the reverting to the previous safe
    state after a collision. The learning agent (yours, or ``agents.TabularAgent``) chooses actions.

Action Space
    ``Discrete(4)``

    ===  ======
    0    north
    1    east
    2    south
    3    west
    ===  ======

Observation
    ``Discrete(height * width)``: the robot's cell, ``row * width + col``. ``info["action_mask"]``
    (int8[4]) marks the actions outside A_d in that cell (eq. 6).

Rewards
    +1 on reaching the goal, -1 on a collision, 0 otherwise.

Termination
    Terminated on reaching the goal, and on a collision when the method has no self-recovery
    (Q-learning, Sarsa, constrained RL). Truncated after ``max_steps`` (200) steps.

Safety guarantee
    When the chosen action runs into an obstacle and the recogniser names its category, the action
    is not executed: ``step`` returns the same cell with reward 0, ``info["prevented"] = True`` and
    the updated mask; the step counter does not advance, and the agent should choose again
    (Algorithm 1, lines 4-10).

Runs and episodes
    ``reset(seed=s)`` starts a new independent run: obstacle placement drawn from
    ``run_seeds(s, run)``, empty A_d, recogniser support set restored. ``reset()`` without a seed
    starts the next episode of the same run (A_d is knowledge that persists).

Registered configurations
    ``SafeNav-5x5-v0``, ``SafeNav-7x7-v0``, ``SafeNav-11x11-v0`` (method ``shield``; pass
    ``method=...`` and ``recogniser=...`` to ``gymnasium.make`` for others).
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pipeline.rl.codes import Outcome, StepFlag
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.recogniser import Recogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import apply_action, empty_added, reasons_with_pictures
from pipeline.rl.runner import make_run_world
from pipeline.rl.structs import MethodParams
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import ACTION_NAMES, Layout, load_layout
from pipeline.world.pictures import N_PICTURES


class SafeNavigationEnv(gym.Env):
    metadata = {"render_modes": ["ansi"]}

    def __init__(self, maze: str | Layout = "5x5", method: str | MethodSpec = "shield",
                 recogniser: Recogniser | None = None, run: int = 0, render_mode: str | None = None):
        self.layout = maze if isinstance(maze, Layout) else load_layout(maze)
        self.method = method if isinstance(method, MethodSpec) else get_method(method)
        self._params = MethodParams.of(self.method)
        self._sees_pictures = reasons_with_pictures(self._params.safety)
        if self._sees_pictures and recogniser is None:
            raise ValueError(f"method {self.method.name!r} reasons with pictures: pass a recogniser")
        if render_mode not in (None, "ansi"):
            raise ValueError(f"render_mode={render_mode!r}: only 'ansi' is supported")
        self.render_mode = render_mode
        self.recogniser = recogniser
        self.run_id = run
        self.geometry = build_geometry(self.layout)
        self.observation_space = spaces.Discrete(self.layout.n_cells)
        self.action_space = spaces.Discrete(4)
        self._added = empty_added()
        self._new_run(0)

    def _new_run(self, seed: int) -> None:
        self.run_seed = seed
        self.world = make_run_world(self.geometry, seed, self.run_id)
        self.unsafe = np.zeros((self.layout.n_cells, 4), dtype=np.bool_)
        self.predicted = np.zeros(N_PICTURES, dtype=np.int8)
        if self._sees_pictures:
            self.recogniser.start_run(self.run_id, run_seeds(seed, self.run_id).recogniser)
            self.predicted[:] = self.recogniser.predictions(self.run_id)
        self.state = self.layout.start
        self.t = 0

    def action_mask(self, state: int | None = None) -> np.ndarray:
        return (~self.unsafe[self.state if state is None else state]).astype(np.int8)

    def _info(self, **extra) -> dict:
        return {"action_mask": self.action_mask(), "step": self.t, **extra}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._new_run(int(seed))
        self.state = self.layout.start
        self.t = 0
        return self.state, self._info(prevented=False, collided=False, picture=-1, flags=0, added=[])

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action {action!r} outside Discrete(4)")
        s = self.state
        p, g = self._params, self.geometry
        out, s2, reward, terminated, flags, picture, n_added = apply_action(
            s, a, p.safety, p.recovery, p.constrained, g.next_cell, g.obstacle, g.ssrl_pairs, self.layout.goal,
            self.world.pictures, self.world.true_category, self.predicted, self.unsafe, self._added)
        added = [tuple(int(x) for x in self._added[k]) for k in range(n_added)]
        recognition = None
        if picture >= 0:
            o = self.geometry.obstacle[s, a]
            recognition = {"picture": int(picture), "predicted": int(self.predicted[picture]),
                           "true": int(self.world.true_category[o])}
        if out == Outcome.prevented:
            return s, 0.0, False, False, self._info(prevented=True, collided=False, picture=int(picture),
                                                    recognition=recognition, flags=0, added=added)
        collided = out == Outcome.collided
        if collided and self._params.dynamic and picture >= 0:
            self.recogniser.learn_from_collision(self.run_id, int(picture), recognition["true"])
            self.predicted[:] = self.recogniser.predictions(self.run_id)
        self.t += 1
        self.state = int(s2)
        truncated = (not terminated) and self.t >= self.method.max_steps
        if truncated:
            flags |= StepFlag.truncated
        return self.state, float(reward), bool(terminated), bool(truncated), self._info(
            prevented=False, collided=collided, picture=int(picture), recognition=recognition,
            flags=int(flags), added=added)

    def render(self):
        grid = [list(row.replace("S", ".")) for row in self.layout.rows]
        r, c = self.layout.cell(self.state)
        grid[r][c] = "R"
        text = "\n".join("".join(row) for row in grid)
        return text + f"\nstep {self.t}  |A_d| = {int(self.unsafe.sum())}  actions {ACTION_NAMES}\n"


for _name in ("5x5", "7x7", "11x11"):
    gym.register(id=f"SafeNav-{_name}-v0", entry_point=SafeNavigationEnv, kwargs={"maze": _name},
                 max_episode_steps=None)
