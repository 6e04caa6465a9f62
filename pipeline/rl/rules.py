"""The world's response to one chosen action, with the method's safety layer and self-recovery
(paper section 3.2.2, 3.3 and Algorithm 1 lines 4-25; DESIGN.md decisions).

``apply_action`` is the single implementation of these rules; the batched runner and the
Gymnasium environment both call it.

Given the robot in free cell ``s`` choosing ``a``:

* ``a`` runs into obstacle ``o`` and the method reasons with pictures (few-shot) -> the robot sees
  the picture of the face of ``o`` toward it. Recognised as its true category: (s, a) joins A_d,
  the action is not executed (``PREVENTED``) and the agent reselects in the same step.
  Misrecognised: the robot collides.
* collision: reward -1, and by method: shield and few-shot add (s, a) to A_d; SSRL adds every
  (free neighbour of o, action toward o). With self-recovery the robot reverts to ``s`` and the
  episode goes on; without it (and always for constrained RL) the episode ends.
* otherwise the move happens (a move off the grid leaves the robot in place), reward +1 and the
  episode ends on reaching the goal, 0 else.
"""
from __future__ import annotations

import numba as nb

from pipeline.rl.sink import (FLAG_COLLIDED, FLAG_GOAL, FLAG_RECOVERED, SOURCE_COLLISION,
                              SOURCE_RECOGNITION, SOURCE_SSRL_RULE)

MOVED = 0
COLLIDED = 1
PREVENTED = 2

SAFETY_NONE = 0
SAFETY_SHIELD = 1
SAFETY_SSRL = 2
SAFETY_FEWSHOT = 3


@nb.njit(cache=True, inline="always")
def _add_unsafe(unsafe, s, a, source, added, n_added):
    if unsafe[s, a]:
        return n_added
    unsafe[s, a] = True
    added[n_added, 0] = s
    added[n_added, 1] = a
    added[n_added, 2] = source
    return n_added + 1


@nb.njit(cache=True)
def apply_action(s, a, next_cell, obstacle, ssrl_pairs, goal, pictures, true_category, predicted,
                 unsafe, safety, recovery, constrained, added):
    """Apply action ``a`` in cell ``s``.

    ``pictures[s, a]`` is this run's picture id table, ``true_category[o]`` the category of
    obstacle ``o``, ``predicted[picture]`` the recogniser's current answer. ``unsafe`` (A_d) is
    updated in place; each addition is written to ``added`` (rows of cell, action, source).

    Returns ``(outcome, next_state, reward, terminal, flags, picture, n_added)`` where ``picture``
    is the picture seen (or -1).
    """
    n_added = 0
    o = obstacle[s, a]
    if o < 0:
        s2 = next_cell[s, a]
        if s2 == goal:
            return MOVED, s2, 1.0, True, FLAG_GOAL, -1, 0
        return MOVED, s2, 0.0, False, 0, -1, 0
    picture = -1
    if safety == SAFETY_FEWSHOT:
        picture = pictures[s, a]
        if predicted[picture] == true_category[o]:
            n_added = _add_unsafe(unsafe, s, a, SOURCE_RECOGNITION, added, n_added)
            return PREVENTED, s, 0.0, False, 0, picture, n_added
    if safety != SAFETY_NONE:
        n_added = _add_unsafe(unsafe, s, a, SOURCE_COLLISION, added, n_added)
    if safety == SAFETY_SSRL:
        for k in range(4):
            c = ssrl_pairs[o, k, 0]
            if c >= 0:
                n_added = _add_unsafe(unsafe, c, ssrl_pairs[o, k, 1], SOURCE_SSRL_RULE, added, n_added)
    if recovery and not constrained:
        return COLLIDED, s, -1.0, False, FLAG_COLLIDED | FLAG_RECOVERED, picture, n_added
    return COLLIDED, s, -1.0, True, FLAG_COLLIDED, picture, n_added
