"""Pictures of the Gymnasium environment's state: a top-down RGB array and a text grid (numpy only).

``rgb_frame`` draws one ``tile`` x ``tile`` square per cell (row 0 at the top, like the layout
file): free cells white with grey grid lines, the start cell pale green, each obstacle filled with
the colour of its category (``CATEGORY_RGB``, in the order of ``world.pictures.CATEGORIES``), the
goal as a yellow oval, every pair (s, a) of A_d as a red bar along the edge of cell ``s`` on the
side of ``a``, and the robot as a blue disc. The colours are constants so tests and viewers can
look for them.
"""

from __future__ import annotations

import numpy as np

from pipeline.world.maze import ACTION_NAMES, Layout
from pipeline.world.pictures import CATEGORIES

FREE_RGB = (255, 255, 255)
GRID_RGB = (190, 190, 190)
START_RGB = (214, 238, 214)
GOAL_RGB = (250, 200, 0)
ROBOT_RGB = (30, 90, 220)
UNSAFE_RGB = (220, 0, 0)
#: One colour per obstacle category (chair, kettle, carton, basin, basket): none red, yellow or blue.
CATEGORY_RGB = ((148, 103, 189), (44, 160, 44), (140, 86, 75), (23, 190, 207), (227, 119, 194))


def _disc(tile: int, rx: float, ry: float) -> np.ndarray:
    """Boolean (tile, tile) mask of an ellipse centred in the tile with radii ``rx``, ``ry`` (in tiles)."""
    c = (np.arange(tile) + 0.5) / tile - 0.5
    return (c[None, :] / rx) ** 2 + (c[:, None] / ry) ** 2 <= 1.0


def rgb_frame(
    layout: Layout, categories: np.ndarray, unsafe: np.ndarray, robot: int, tile: int = 32
) -> np.ndarray:
    """The maze seen from above, ``(height * tile, width * tile, 3)`` uint8.

    ``categories[o]`` is the category of obstacle ``o`` (the order of ``layout.obstacles``),
    ``unsafe`` the (n_cells, 4) A_d, ``robot`` the robot's cell."""
    if tile < 8:
        raise ValueError(f"tile size {tile} too small to draw: use 8 pixels or more")
    h, w = layout.height, layout.width
    img = np.empty((h * tile, w * tile, 3), dtype=np.uint8)
    img[:] = GRID_RGB

    def cell_view(cell: int) -> np.ndarray:
        r, c = layout.cell(cell)
        return img[r * tile : (r + 1) * tile, c * tile : (c + 1) * tile]

    for cell in range(layout.n_cells):
        cell_view(cell)[1:, 1:] = FREE_RGB  # row 0 and column 0 of each tile are its grid lines
    cell_view(layout.start)[1:, 1:] = START_RGB
    for o, cell in enumerate(layout.obstacles):
        cell_view(cell)[1:, 1:] = CATEGORY_RGB[int(categories[o])]
    cell_view(layout.goal)[_disc(tile, 0.38, 0.28)] = GOAL_RGB
    bar = max(2, tile // 8)
    edges = (
        np.s_[1 : 1 + bar, 1:],
        np.s_[1:, tile - bar :],
        np.s_[tile - bar :, 1:],
        np.s_[1:, 1 : 1 + bar],
    )  # N E S W
    for cell, a in np.argwhere(unsafe):
        cell_view(int(cell))[edges[int(a)]] = UNSAFE_RGB
    cell_view(robot)[_disc(tile, 0.3, 0.3)] = ROBOT_RGB
    return img


def ansi_frame(
    layout: Layout, categories: np.ndarray, unsafe: np.ndarray, robot: int, step: int
) -> str:
    """The layout as text: ``R`` the robot, ``S`` start, ``G`` goal, ``.`` free, each obstacle as the
    digit of its category; then the step, |A_d| and the legend."""
    grid = [list(row.replace("X", "?")) for row in layout.rows]
    for o, cell in enumerate(layout.obstacles):
        r, c = layout.cell(cell)
        grid[r][c] = str(int(categories[o]))
    r, c = layout.cell(robot)
    grid[r][c] = "R"
    legend = ", ".join(f"{k} {name}" for k, name in enumerate(CATEGORIES))
    return (
        "\n".join("".join(row) for row in grid)
        + f"\nstep {step}  |A_d| = {int(unsafe.sum())}  actions {' '.join(ACTION_NAMES)}"
        + f"\nobstacles: {legend}\n"
    )
