"""Action selection with the safety guarantee and the tabular updates (paper eqs. 6-9).

These numba functions are the single implementation of the agent's rules: the batched trial
runner (``kernel.py``) and the Gymnasium agent (``agents.py``) both call them, so both front doors
draw the same random numbers in the same order.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from pipeline.rl.rng import randint, uniform


@nb.njit(cache=True, inline="always")
def _argmax_random_ties(q_row, unsafe_row, only_allowed, rng, i):
    best = -np.inf
    count = 0
    for a in range(4):
        if only_allowed and unsafe_row[a]:
            continue
        v = q_row[a]
        if v > best:
            best = v
            count = 1
        elif v == best:
            count += 1
    if count == 0:
        return -1
    pick = 0 if count == 1 else randint(rng, i, count)
    for a in range(4):
        if only_allowed and unsafe_row[a]:
            continue
        if q_row[a] == best:
            if pick == 0:
                return a
            pick -= 1
    return -1


@nb.njit(cache=True, inline="always")
def _random_allowed(unsafe_row, rng, i):
    n = 0
    for a in range(4):
        if not unsafe_row[a]:
            n += 1
    if n == 0:
        return -1
    k = randint(rng, i, n)
    for a in range(4):
        if not unsafe_row[a]:
            if k == 0:
                return a
            k -= 1
    return -1


@nb.njit(cache=True)
def select_action(q_row, unsafe_row, epsilon, rng, i):
    """epsilon-greedy with the safety guarantee, eqs. 7 (greedy) and 8 (random).

    With probability epsilon a uniformly random action, otherwise argmax Q (ties at random). If
    that action lies in A_d (``unsafe_row``), it is reselected: argmax Q' or random over the
    allowed actions. Returns ``(action, reselected)``. If every action is unsafe (an enclosed
    cell) the first choice stands.
    """
    if uniform(rng, i) < epsilon:
        a = randint(rng, i, 4)
        if unsafe_row[a]:
            b = _random_allowed(unsafe_row, rng, i)
            if b >= 0:
                return b, True
        return a, False
    a = _argmax_random_ties(q_row, unsafe_row, False, rng, i)
    if unsafe_row[a]:
        b = _argmax_random_ties(q_row, unsafe_row, True, rng, i)
        if b >= 0:
            return b, True
    return a, False


@nb.njit(cache=True, inline="always")
def max_allowed(q_row, unsafe_row):
    """max over Q' (actions outside A_d) of one state, the bootstrap of eq. 9."""
    best = -np.inf
    for a in range(4):
        if not unsafe_row[a] and q_row[a] > best:
            best = q_row[a]
    if best == -np.inf:
        for a in range(4):
            if q_row[a] > best:
                best = q_row[a]
    return best


@nb.njit(cache=True, inline="always")
def td_update(q, s, a, target, alpha):
    """Q(s,a) <- Q(s,a) + alpha [target - Q(s,a)] (eq. 9)."""
    q[s, a] += alpha * (target - q[s, a])


@nb.njit(cache=True)
def greedy_path_is_optimal(q, unsafe, maze):
    """True iff the greedy policy over the allowed actions, with a unique argmax at every step,
    walks from ``maze``'s start to its goal in ``maze.optimal_length`` moves (i.e. follows an
    optimal path; ``maze`` a ``structs.MazeArrays``)."""
    s = maze.start
    for _ in range(maze.optimal_length):
        best = -np.inf
        arg = -1
        unique = False
        for a in range(4):
            if unsafe[s, a]:
                continue
            v = q[s, a]
            if v > best:
                best = v
                arg = a
                unique = True
            elif v == best:
                unique = False
        if arg < 0 or not unique or maze.obstacle[s, arg] >= 0:
            return False
        s = maze.next_cell[s, arg]
        if s == maze.goal:
            return True
    return s == maze.goal
