"""The world's response to one chosen action, with the method's safety layer and self-recovery
(paper section 3.2.2, 3.3 and Algorithm 1 lines 4-25; where the paper is vague, the decisions of
README "Where we differ from the paper").

``apply_action`` is the single implementation of these rules; the batched kernel and the
Gymnasium environment both call it. It is also the only code that tells safety methods apart
(:class:`Safety`, defined here) and the one place that declares the methods of ``conf/method/``
(:data:`METHODS`: display name, colour, order). Adding a method means a member and a branch in this
file if its rule is new (and a line in ``reasons_with_pictures`` if it looks at pictures), its entry
in :data:`METHODS`, its yaml and a test (docs/extending.md).

Given the robot in free cell ``s`` choosing ``a``:

* ``a`` runs into obstacle ``o`` and the method reasons with pictures (few-shot) -> the robot sees
  the picture of the face of ``o`` toward it, and the decision rule (:class:`Rule`) says whether it
  stops: under the paper's rule when the prediction names ``o``'s true category. A stop: (s, a)
  joins A_d, the action is not executed (``Outcome.prevented``) and the agent reselects in the same
  step. Otherwise the robot collides.
* collision: reward -1, and by method: shield and few-shot add (s, a) to A_d; SSRL adds every
  (free neighbour of o, action toward o). With self-recovery the robot reverts to ``s`` and the
  episode goes on; without it (and always for constrained RL) the episode ends.
* otherwise the move happens (a move off the grid leaves the robot in place), reward +1 and the
  episode ends on reaching the goal, 0 else.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numba as nb
import numpy as np

from pipeline.rl.codes import Outcome, Source, StepFlag


class Safety(IntEnum):
    """How a method's unsafe set A_d grows (paper section 3.2.2 and the baselines of 4.2.2).

    Each member's rule is a branch of ``rules.apply_action``; nothing else branches on these.
    """

    none = 0  #: no safety layer (Q-learning, Sarsa, constrained RL)
    shield = 1  #: online shield: a collision from (s, a) adds (s, a)
    ssrl = 2  #: SSRL: a collision with o adds every (free neighbour of o, action toward o)
    fewshot = (
        3  #: Algorithm 1: a recognised obstacle adds (s, a); a misrecognition collides and adds it
    )


class Rule(IntEnum):
    """When a method that reasons with pictures stops before an obstacle it sees (section 3.2.2).
    The same rule in every world: the grid's query pictures and the robot's live pictures meet it
    through the one kernel; a comparison between worlds or methods holds it fixed.
    """

    paper = 0  #: the paper's: the prediction names the obstacle's true category (Algorithm 1)
    open_set = 1  #: the top score of the picture is at least the threshold, whatever it names
    range = (
        2  #: the range sensor alone: every occupied cell ahead (the picture is still classified)
    )


@dataclass(frozen=True)
class Method:
    """What the rest of the code knows of a method of ``conf/method/`` beyond its fields: how the
    report names and draws it. Never recorded (the records keep ``MethodSpec``'s fields only), so
    changing a display name or a colour changes the report, not the records."""

    name: str
    """Its config name: ``conf/method/<name>.yaml`` and ``MethodSpec.name``."""
    display: str
    """Its name in tables, legends and the claims."""
    colour: str
    """Its colour in every figure where a series is one method (a matplotlib colour)."""


#: Every method of ``conf/method/``, in the order of the report's tables and figures (the paper's
#: Figure 8, then Table 3's rows); ``tests/test_declarations.py`` checks it against the yaml files.
METHODS = (
    Method("qlearning", "Q-learning", "#7f7f7f"),
    Method("sarsa", "Sarsa", "#bcbd22"),
    Method("shield", "Shield", "#2ca02c"),
    Method("ssrl", "SSRL", "#d62728"),
    Method("constrained", "Constrained RL", "#9467bd"),
    Method("fewshot", "Few-shot (static support set)", "#1f77b4"),
    Method("fewshot_dss", "Few-shot + DSS", "#ff7f0e"),
)


#: The most pairs one step can add to A_d (SSRL: the pair itself and up to four neighbours').
MAX_ADDED = 8


@nb.njit(cache=True)
def empty_added():
    """A scratch array for ``apply_action``'s additions to A_d: rows ``(cell, action, source)``."""
    return np.empty((MAX_ADDED, 3), dtype=np.int64)


@nb.njit(cache=True)
def reasons_with_pictures(safety):
    """Whether the safety rule looks at the picture of the obstacle ahead (and so needs a
    recogniser): few-shot, Algorithm 1 lines 4-10."""
    return safety == Safety.fewshot


@nb.njit(cache=True, inline="always")
def _add_unsafe(unsafe, s, a, source, added, n_added):
    if unsafe[s, a]:
        return n_added
    unsafe[s, a] = True
    added[n_added, 0] = s  # a row of ``added`` is (cell, action, source)
    added[n_added, 1] = a
    added[n_added, 2] = source
    return n_added + 1


@nb.njit(cache=True, inline="always")
def stops(rule, names_true_category, confident):
    """Whether the robot stops before the obstacle it sees, under decision rule ``rule``."""
    if rule == Rule.paper:
        return names_true_category
    if rule == Rule.open_set:
        return confident
    return True


# Inlined into the kernel's step loop, where the records then cost nothing (a call would
# reference-count each of their arrays every step). From Python: ``gym_env._apply_action``.
@nb.njit(cache=True, inline="always")
def apply_action(s, a, method, maze, sight, unsafe, added):
    """Apply action ``a`` in cell ``s`` under ``method``'s safety rule ``safety`` (a ``Safety``),
    decision rule ``rule`` (a :class:`Rule`), ``recovery`` and ``constrained``
    (``structs.MethodParams``), in ``maze`` (``structs.MazeArrays``: ``next_cell``, ``obstacle``,
    ``ssrl_pairs``, ``goal``), with what the run sees (``structs.Sights`` of one run:
    ``pictures[s, a]`` the picture id on the face ahead, ``true_category[o]`` obstacle ``o``'s
    category, ``predicted[picture]`` the recogniser's current answer, ``confident[picture]`` whether
    its top score reaches the open-set threshold). ``unsafe`` (A_d) is updated in place; each
    addition is written to a row ``(cell, action, source)`` of ``added`` (``empty_added``;
    ``source`` a ``Source``).

    Returns ``(outcome, next_state, reward, terminal, flags, picture, n_added)``: an ``Outcome``
    value (an int: numba hands enum members to Python slowly), ``StepFlag`` bits, the picture seen
    (or -1) and the number of rows written to ``added``.
    """
    n_added = 0
    o = maze.obstacle[s, a]
    if o < 0:
        s2 = maze.next_cell[s, a]
        if s2 == maze.goal:
            return Outcome.moved.value, s2, 1.0, True, StepFlag.goal, -1, 0
        return Outcome.moved.value, s2, 0.0, False, 0, -1, 0
    picture = -1
    if reasons_with_pictures(method.safety):
        picture = sight.pictures[s, a]
        names_true_category = sight.predicted[picture] == sight.true_category[o]
        if stops(method.rule, names_true_category, sight.confident[picture]):
            n_added = _add_unsafe(unsafe, s, a, Source.recognition, added, n_added)
            return Outcome.prevented.value, s, 0.0, False, 0, picture, n_added
    if method.safety != Safety.none:
        n_added = _add_unsafe(unsafe, s, a, Source.collision, added, n_added)
    if method.safety == Safety.ssrl:
        for k in range(4):
            c = maze.ssrl_pairs[o, k, 0]
            if c >= 0:
                pair = maze.ssrl_pairs[o, k, 1]
                n_added = _add_unsafe(unsafe, c, pair, Source.ssrl_rule, added, n_added)
    if method.recovery and not method.constrained:
        return (
            Outcome.collided.value,
            s,
            -1.0,
            False,
            StepFlag.collided | StepFlag.recovered,
            picture,
            n_added,
        )
    return Outcome.collided.value, s, -1.0, True, StepFlag.collided, picture, n_added
