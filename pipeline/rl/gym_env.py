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
    (Q-learning, Sarsa, constrained RL).

Truncation
    After the method's ``max_steps`` (200) executed moves: ``truncated`` and ``StepFlag.truncated``
    in ``info["flags"]``; ``info["step"]`` counts the moves. ``gymnasium.make`` adds its
    ``TimeLimit`` with the registered ``max_episode_steps``, the same 200, which counts ``step``
    calls: the two agree on every step unless actions were prevented (below; only few-shot methods
    prevent), and then the wrapper cuts the episode one move earlier per prevented call. For the
    paper's count with a few-shot method pass ``max_episode_steps=-1`` to ``gymnasium.make`` (no
    wrapper; the environment still truncates after ``max_steps`` moves). To change the length,
    change both: ``method=get_method("fewshot", max_steps=n)`` and ``max_episode_steps=n``.

Safety guarantee
    When the chosen action runs into an obstacle and the decision rule stops it (``rule``:
    ``paper``, the recogniser names its category; ``open_set``, its top score reaches ``threshold``;
    ``range``, always; ``rules.Rule``), the action is not executed: ``step`` returns the same cell
    with reward 0, ``info["prevented"] = True`` and the updated mask; the step counter does not
    advance, and the agent should choose again (Algorithm 1, lines 4-10).

Runs and episodes
    ``reset(seed=s)`` starts a new independent run: obstacle placement drawn from
    ``run_seeds(s, run)``, empty A_d, recogniser support set restored. ``reset()`` without a seed
    starts the next episode of the same run (A_d is knowledge that persists).

Arguments
    ``maze`` (built-in name or ``Layout``), ``method`` (name in ``conf/method/`` or
    ``MethodSpec``), ``recogniser`` (an object of the ``pipeline.rl.recogniser.Recogniser``
    protocol, needed by the methods that reason with pictures, ``fewshot`` and ``fewshot_dss``; by
    name through ``pipeline.envs.make_env``, as ``rl`` never imports ``fewshot``), ``run``,
    ``render_mode``, ``tile_size`` (pixels per cell of ``rgb_array``), ``rule`` and ``threshold``
    (the decision rule), ``world`` (``rl.run_world``: the grid, or the camera robot's
    ``RobotWorld``, which ``SafeNav3D-*`` passes).

Render modes
    ``"rgb_array"``: the maze from above, ``width * tile_size`` wide, a legend strip under it, uint8
    (drawn by ``pipeline.rl.gym_render`` in the one palette of ``pipeline/palette.py``: the replay
    and the report use the same colours). ``"ansi"``: the same as a text grid (obstacles as
    category digits). ``metadata["render_fps"]`` is 4.

Registered configurations
    ``SafeNav-5x5-v0``, ``SafeNav-7x7-v0``, ``SafeNav-11x11-v0`` (that maze only) and
    ``SafeNav-v0`` (any ``maze=``, 5x5 by default): method ``shield``, ``max_episode_steps=200``,
    registered on ``import pipeline`` (``pipeline.registration``). Other methods and recognisers
    by keyword: ``gymnasium.make("SafeNav-5x5-v0", method="fewshot_dss", recogniser="oracle")``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numba as nb
import numpy as np
from gymnasium import spaces

from pipeline.rl.codes import Outcome, StepFlag
from pipeline.rl.gym_render import ansi_frame, rgb_frame
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.recogniser import Recogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import Rule, apply_action, empty_added, reasons_with_pictures
from pipeline.rl.run_world import GRID, World
from pipeline.rl.structs import MazeArrays, MethodParams, Sights
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import Layout, load_layout

#: How to pass a recogniser, for the error messages.
HOW_TO_PASS = (
    "pass recogniser=<name> to gymnasium.make or pipeline.envs.make_env (a file of "
    "conf/recogniser/: relation_net, oracle, fixed_accuracy), or a Recogniser object "
    "(pipeline.rl.recogniser) to SafeNavigationEnv"
)


@nb.njit(cache=True)
def _apply_action(s, a, method, maze, sight, unsafe, added):
    """``rules.apply_action`` for a caller in Python, its records given as plain tuples: numba
    types a plain tuple from Python several times faster than a named one, and this environment
    calls it every step."""
    method, maze, sight = MethodParams(*method), MazeArrays(*maze), Sights(*sight)
    return apply_action(s, a, method, maze, sight, unsafe, added)


class SafeNavigationEnv(gym.Env):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["ansi", "rgb_array"], "render_fps": 4}

    def __init__(
        self,
        maze: str | Layout = "5x5",
        method: str | MethodSpec = "shield",
        recogniser: Recogniser | None = None,
        run: int = 0,
        render_mode: str | None = None,
        tile_size: int = 32,
        rule: str | Rule = Rule.paper,
        threshold: float = 0.5,
        world: World = GRID,
    ):
        self.layout = maze if isinstance(maze, Layout) else load_layout(maze)
        self.method = method if isinstance(method, MethodSpec) else get_method(method)
        self._params = MethodParams.of(self.method, rule)
        if not 0.0 < float(threshold) <= 1.0:
            raise ValueError(f"threshold={threshold}: must lie in (0, 1]")
        self.rule = Rule(self._params.rule)
        self.threshold = float(threshold)
        self.world_model = world
        self._sees_pictures = reasons_with_pictures(self._params.safety)
        if isinstance(recogniser, str):
            raise TypeError(
                f"SafeNavigationEnv takes a Recogniser object, not the name {recogniser!r}: {HOW_TO_PASS}"
            )
        if self._sees_pictures and recogniser is None:
            raise ValueError(
                f"method {self.method.name!r} reasons with pictures and needs a recogniser: {HOW_TO_PASS}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r}: expected one of {', '.join(self.metadata['render_modes'])} or None"
            )
        if int(tile_size) < 8:
            raise ValueError(f"tile_size={tile_size}: too small to draw, use 8 pixels or more")
        self.render_mode = render_mode
        self.tile_size = int(tile_size)
        self.recogniser = recogniser
        self.run_id = run
        self.geometry = build_geometry(self.layout)
        self.observation_space = spaces.Discrete(self.layout.n_cells)
        self.action_space = spaces.Discrete(4)
        self._added = empty_added()
        # what apply_action reads of the method and the maze, as plain tuples (see _apply_action)
        self._records = tuple(self._params), tuple(MazeArrays.of(self.layout, self.geometry))
        self._new_run(0)
        self.state, self.t = self.layout.start, 0  # until reset(), which starts them again

    def _new_run(self, seed: int) -> None:
        self.world = self.world_model.run_world(self.geometry, seed, self.run_id)
        self.unsafe = np.zeros((self.layout.n_cells, 4), dtype=np.bool_)
        n_pictures = max(1, len(self.world_model.picture_category))
        self.predicted = np.zeros(n_pictures, dtype=np.int8)
        self.confident = np.zeros(n_pictures, dtype=np.bool_)
        # what apply_action reads of what the run sees (the answers are updated in place)
        self._sight = (
            self.world.pictures,
            self.world.true_category,
            self.predicted,
            self.confident,
        )
        if self._sees_pictures:
            self.recogniser.start_run(self.run_id, run_seeds(seed, self.run_id).recogniser)
            self._answer()

    def _answer(self) -> None:
        """The recogniser's answers under the run's current support set (as the runner's)."""
        self.predicted[:] = self.recogniser.predictions(self.run_id)
        if self.rule == Rule.open_set:
            seen = self.world.seen
            scores = np.asarray(self.recogniser.scores(self.run_id, seen))
            self.confident[seen] = scores.max(axis=1) >= self.threshold

    def action_mask(self, state: int | None = None) -> np.ndarray:
        return (~self.unsafe[self.state if state is None else state]).astype(np.int8)

    def _info(self, **seen) -> dict:
        """``info``: the action mask, the move counter and what the step saw (``reset``: nothing)."""
        nothing = dict(prevented=False, collided=False, picture=-1, recognition=None, flags=0)
        return {"action_mask": self.action_mask(), "step": self.t, **nothing, "added": [], **seen}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._new_run(int(seed))
        self.state = self.layout.start
        self.t = 0
        return self.state, self._info()

    def step(self, action):
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action {action!r} outside Discrete(4)")
        s = self.state
        out, s2, reward, terminated, flags, picture, n_added = _apply_action(
            s, a, *self._records, self._sight, self.unsafe, self._added
        )
        added = [tuple(int(x) for x in self._added[k]) for k in range(n_added)]
        recognition = None
        if picture >= 0:
            o = self.geometry.obstacle[s, a]
            recognition = {
                "picture": int(picture),
                "predicted": int(self.predicted[picture]),
                "true": int(self.world.true_category[o]),
            }
        prevented, collided = out == Outcome.prevented, out == Outcome.collided
        if collided and self._params.dynamic and picture >= 0:
            self.recogniser.learn_from_collision(self.run_id, int(picture), recognition["true"])
            self._answer()
        # a prevented action stays in s (reward 0, flags 0) and is no move: the counter waits
        truncated = False
        if not prevented:
            self.t += 1
            self.state = int(s2)
            truncated = (not terminated) and self.t >= self.method.max_steps
            if truncated:
                flags |= StepFlag.truncated
        info = self._info(
            prevented=prevented,
            collided=collided,
            picture=int(picture),
            recognition=recognition,
            flags=int(flags),
            added=added,
        )
        return self.state, float(reward), bool(terminated), truncated, info

    def render(self):
        """``rgb_array``: the top-down picture; ``ansi``: the text grid (see Render modes)."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() without a render_mode: make the environment with "
                "render_mode='rgb_array' or 'ansi'"
            )
            return None
        categories = self.world.true_category
        if self.render_mode == "rgb_array":
            return rgb_frame(self.layout, categories, self.unsafe, self.state, self.tile_size)
        return ansi_frame(self.layout, categories, self.unsafe, self.state, self.t)
