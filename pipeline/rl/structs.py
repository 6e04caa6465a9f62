"""The named records the numba code passes around: a method's parameters, the maze's lookup
tables, what a run's robot sees, each run's learning state, and the buffers the kernel fills
(:class:`Logs`).

They are ``typing.NamedTuple`` classes of numpy arrays and scalars, which numba compiles as
structs: ``state.q[r]`` costs what a positional array argument costs. In the kernel every array
of ``Sights``, ``RunState``, ``Results``, ``Trace``, ``Recognitions``, ``Additions`` and
``Substitution`` has a leading run axis (row ``r`` belongs to run ``r``), so a run pauses and resumes exactly.

Codes (learner, safety rule, outcomes, flags, sources) are the IntEnums of ``codes.py``; here
they are stored as plain ints (see there why).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pipeline.rl.codes import Learner, member
from pipeline.rl.rules import Rule, Safety
from pipeline.world.geometry import Geometry
from pipeline.world.maze import Layout, shortest_path_length


class MethodParams(NamedTuple):
    """A method's hyperparameters and rule switches (``methods.MethodSpec``, conf/method/*.yaml)."""

    gamma: float  #: discount (eq. 9)
    alpha: float  #: learning rate (eq. 9)
    epsilon_decay: float  #: constrained RL: epsilon drops by this much per violation
    epsilon_min: float  #: ... down to this floor
    learner: int  #: a ``Learner`` code
    safety: int  #: a ``Safety`` code: how A_d grows (``rules.apply_action``)
    recovery: bool  #: a collision reverts the robot and the episode goes on
    constrained: bool  #: constrained RL: every violation ends the episode and decays epsilon
    dynamic: bool  #: misrecognised pictures substitute into the dynamic support set (section 3.3)
    max_steps: int  #: steps per episode before truncation
    rule: int  #: a ``Rule`` code: when a picture stops the robot (``rules.stops``)

    @classmethod
    def of(cls, method, rule: int | str = Rule.paper) -> MethodParams:
        """From a ``MethodSpec`` and the decision rule (a ``Rule``, or its name); the method's
        learner and safety may be config strings or enum members."""
        return cls(
            float(method.gamma),
            float(method.alpha),
            float(method.epsilon_decay),
            float(method.epsilon_min),
            int(member(Learner, method.learner)),
            int(member(Safety, method.safety)),
            bool(method.recovery),
            bool(method.constrained),
            bool(method.dynamic_support),
            int(method.max_steps),
            int(rule if isinstance(rule, int) else member(Rule, rule)),
        )


class MazeArrays(NamedTuple):
    """One layout's lookup tables (``world.geometry.Geometry``) and its start and goal."""

    next_cell: (
        np.ndarray
    )  #: (n_cells, 4) cell reached by a; s itself off the grid or into an obstacle
    obstacle: (
        np.ndarray
    )  #: (n_cells, 4) obstacle that a runs into from s, or -1 (dangerous pairs, eq. 4)
    ssrl_pairs: np.ndarray  #: (n_obstacles, 4, 2) the (cell, action toward o) pairs of o, -1 padded
    start: int
    goal: int
    optimal_length: int  #: moves of a shortest start-goal path

    @classmethod
    def of(cls, layout: Layout, geometry: Geometry) -> MazeArrays:
        return cls(
            geometry.next_cell,
            geometry.obstacle,
            geometry.ssrl_pairs,
            int(layout.start),
            int(layout.goal),
            int(shortest_path_length(layout)),
        )


class Sights(NamedTuple):
    """What each run's robot sees and what its recogniser answers (leading run axis)."""

    pictures: np.ndarray  #: (runs, n_cells, 4) int16 picture id on the obstacle face ahead, or -1
    true_category: np.ndarray  #: (runs, n_obstacles) int8 category of each obstacle
    predicted: np.ndarray  #: (runs, n_pictures) int8 the recogniser's current answer per picture
    confident: np.ndarray  #: (runs, n_pictures) bool its top score reaches the open-set threshold


class RunState(NamedTuple):
    """Everything a run carries from one step to the next (leading run axis)."""

    q: np.ndarray  #: (runs, n_cells, 4) float64 Q table
    unsafe: np.ndarray  #: (runs, n_cells, 4) bool A_d
    rng: np.ndarray  #: (runs,) uint64 the agent's splitmix64 state (``rng.py``)
    episode: np.ndarray  #: (runs,) int64 current episode
    step: np.ndarray  #: (runs,) int64 steps taken in it
    cell: np.ndarray  #: (runs,) int64 the robot's cell
    pending_action: (
        np.ndarray
    )  #: (runs,) int64 Sarsa's next action chosen at the last update, or -1
    pending_reselected: np.ndarray  #: (runs,) bool ... and whether choosing it reselected
    collisions: np.ndarray  #: (runs,) int64 collisions in the current episode
    prevented: np.ndarray  #: (runs,) int64 prevented actions in the current episode
    epsilon: np.ndarray  #: (runs,) float64 exploration rate (eqs. 7-8)
    ep_return: np.ndarray  #: (runs,) float64 return of the current episode so far

    @classmethod
    def fresh(
        cls, runs: int, n_cells: int, start: int, epsilon: float, rng: np.ndarray
    ) -> RunState:
        def ints(value=0):
            return np.full(runs, value, np.int64)

        return cls(
            np.zeros((runs, n_cells, 4)),
            np.zeros((runs, n_cells, 4), np.bool_),
            rng,
            ints(),
            ints(),
            ints(start),
            ints(-1),
            np.zeros(runs, np.bool_),
            ints(),
            ints(),
            np.full(runs, float(epsilon)),
            np.zeros(runs),
        )


class Results(NamedTuple):
    """Per-episode outcomes, (runs, episodes) each."""

    steps: np.ndarray  #: int32
    collisions: np.ndarray  #: int32
    returns: np.ndarray  #: float32
    reached_goal: np.ndarray  #: bool
    prevented: np.ndarray  #: int32
    greedy_optimal: np.ndarray  #: bool: the greedy policy walks an optimal path after the episode
    epsilon: np.ndarray  #: float32 at the end of the episode

    @classmethod
    def zeros(cls, runs: int, episodes: int) -> Results:
        shape = (runs, episodes)
        return cls(
            np.zeros(shape, np.int32),
            np.zeros(shape, np.int32),
            np.zeros(shape, np.float32),
            np.zeros(shape, np.bool_),
            np.zeros(shape, np.int32),
            np.zeros(shape, np.bool_),
            np.zeros(shape, np.float32),
        )


class Trace(NamedTuple):
    """The steps of each run's finished, not yet emitted episodes (``sink.py`` batch fields)."""

    record: bool  #: keep the trace at all (a sink is listening)
    states: np.ndarray  #: (runs, capacity) int32
    actions: np.ndarray  #: (runs, capacity) int8
    rewards: np.ndarray  #: (runs, capacity) float32
    flags: np.ndarray  #: (runs, capacity) uint8 ``StepFlag`` bits
    length: np.ndarray  #: (runs,) int64 steps held

    @classmethod
    def empty(cls, runs: int, capacity: int, record: bool) -> Trace:
        return cls(
            bool(record),
            np.zeros((runs, capacity), np.int32),
            np.zeros((runs, capacity), np.int8),
            np.zeros((runs, capacity), np.float32),
            np.zeros((runs, capacity), np.uint8),
            np.zeros(runs, np.int64),
        )


def _empty_log(cls, runs: int, capacity: int):
    """An empty log (:class:`Recognitions`, :class:`Additions`): ``capacity`` rows a run of every
    field, and ``length`` (runs,), the rows held."""
    rows = (np.zeros((runs, capacity), np.int64) for _ in cls._fields[:-1])
    return cls(*rows, np.zeros(runs, np.int64))


class Recognitions(NamedTuple):
    """Every picture a run's robot saw, in order: (runs, capacity) int64 each."""

    episode: np.ndarray
    step: np.ndarray
    state: np.ndarray
    action: np.ndarray
    picture: np.ndarray
    predicted: np.ndarray  #: the recogniser's answer then
    true: np.ndarray  #: the obstacle's category
    length: np.ndarray  #: (runs,) rows held

    empty = classmethod(_empty_log)


class Additions(NamedTuple):
    """Every pair (s, a) that joined a run's A_d, in order: (runs, capacity) int64 each."""

    episode: np.ndarray
    step: np.ndarray
    state: np.ndarray
    action: np.ndarray
    source: np.ndarray  #: a ``Source`` code
    length: np.ndarray  #: (runs,) rows held

    empty = classmethod(_empty_log)


class Substitution(NamedTuple):
    """A run's pending support-set substitution (``Status.substitute``): (runs,) int64 each."""

    episode: np.ndarray
    step: np.ndarray
    picture: np.ndarray  #: the misrecognised picture
    category: np.ndarray  #: its true category

    @classmethod
    def empty(cls, runs: int) -> Substitution:
        return cls(*(np.zeros(runs, np.int64) for _ in range(4)))


class Logs(NamedTuple):
    """What the kernel writes down for the runner while runs advance: the step trace, the
    recognitions, the A_d additions and a pending substitution (one argument, not four)."""

    trace: Trace
    recognitions: Recognitions
    additions: Additions
    substitution: Substitution

    @classmethod
    def empty(cls, trace: Trace, runs: int, capacity: int) -> Logs:
        """Empty logs of ``runs`` runs around ``trace``: ``capacity`` recognitions and additions
        a run (each dangerous pair, eq. 4, is seen and joins A_d at most once a run)."""
        return cls(
            trace,
            Recognitions.empty(runs, capacity),
            Additions.empty(runs, capacity),
            Substitution.empty(runs),
        )
