"""Transitions, critical states and dangerous actions of a layout (paper section 3.2.2, eqs. 3-4).

Everything here depends on the layout only, not on which obstacle stands where.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.world.maze import MOVES, N_ACTIONS, Layout

#: The action that moves from an obstacle's neighbour on world side ``d`` toward the obstacle.
#: A robot on the north side (d=0) must move south (a=2): ``toward = (d + 2) % 4``.
OPPOSITE = np.array([2, 3, 0, 1], dtype=np.int8)


@dataclass(frozen=True)
class Geometry:
    """Lookup tables over (cell, action), each of shape ``(n_cells, 4)``.

    next_cell[s, a]  cell reached by a legal move; ``s`` itself for a move off the grid and for a
                     move into an obstacle (the move does not happen).
    obstacle[s, a]   index (into ``layout.obstacles``) of the obstacle that ``a`` runs into from
                     ``s``, or -1. Non-negative exactly on the dangerous pairs of eq. 4.
    side[s, a]       world side (0 N, 1 E, 2 S, 3 W) of that obstacle on which ``s`` lies, or -1.
    ssrl_pairs[o]    the (cell, action) pairs toward obstacle ``o`` from its free neighbours,
                     shape ``(n_obstacles, 4, 2)``, padded with -1 (used by SSRL's rule).
    """

    layout: Layout
    next_cell: np.ndarray
    obstacle: np.ndarray
    side: np.ndarray
    ssrl_pairs: np.ndarray

    @property
    def critical_states(self) -> np.ndarray:
        """S_c of eq. 3: free cells with an obstacle one move away."""
        return np.flatnonzero((self.obstacle >= 0).any(axis=1))

    @property
    def dangerous_pairs(self) -> np.ndarray:
        """(s_tc, a_td) pairs of eq. 4, shape ``(n, 2)``, sorted by cell then action."""
        return np.argwhere(self.obstacle >= 0)


def build_geometry(layout: Layout) -> Geometry:
    """The lookup tables, vectorised over cells (a 1000x1000 layout takes well under a second)."""
    h, w, n = layout.height, layout.width, layout.n_cells
    blocked = layout.is_obstacle()
    index_of = np.full(n, -1, dtype=np.int64)
    index_of[list(layout.obstacles)] = np.arange(len(layout.obstacles))
    cells = np.arange(n, dtype=np.int64)
    row, col = np.divmod(cells, w)
    next_cell = np.empty((n, N_ACTIONS), dtype=np.int32)
    obstacle = np.full((n, N_ACTIONS), -1, dtype=np.int32)
    side = np.full((n, N_ACTIONS), -1, dtype=np.int8)
    ssrl_pairs = np.full((len(layout.obstacles), N_ACTIONS, 2), -1, dtype=np.int32)
    for a, (dr, dc) in enumerate(MOVES):
        r2, c2 = row + dr, col + dc
        inside = (r2 >= 0) & (r2 < h) & (c2 >= 0) & (c2 < w)
        target = np.where(inside, r2 * w + c2, cells)
        into_obstacle = inside & blocked[target]
        next_cell[:, a] = np.where(inside & ~into_obstacle, target, cells)
        danger = into_obstacle & ~blocked
        o = index_of[target[danger]]
        obstacle[danger, a] = o
        side[danger, a] = OPPOSITE[a]
        ssrl_pairs[o, OPPOSITE[a], 0] = cells[danger]
        ssrl_pairs[o, OPPOSITE[a], 1] = a
    return Geometry(layout, next_cell, obstacle, side, ssrl_pairs)
