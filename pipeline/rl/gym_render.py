"""Pictures of the Gymnasium environment's state: a top-down RGB array and a text grid.

``rgb_frame`` draws one ``tile`` x ``tile`` square per cell (row 0 at the top, like the layout
file): free cells white with grey grid lines, the start cell in the start colour, each obstacle
filled with the colour of its category, the goal as an oval, every pair (s, a) of A_d as a bar
along the edge of cell ``s`` on the side of ``a``, and the robot as a disc; below the maze a legend
strip names each colour. Every colour is the study's one palette (:mod:`pipeline.palette`), so a
category has the same colour here as in the replay and the report.
"""

from __future__ import annotations

import numpy as np

from pipeline import palette
from pipeline.world.maze import ACTION_NAMES, Layout
from pipeline.world.pictures import CATEGORIES

FREE_RGB = palette.rgb(palette.FREE)
GRID_RGB = palette.rgb(palette.GRID)
START_RGB = palette.rgb(palette.START)
GOAL_RGB = palette.rgb(palette.GOAL)
ROBOT_RGB = palette.rgb(palette.ROBOT)
UNSAFE_RGB = palette.rgb(palette.UNSAFE)
#: One colour per obstacle category, in the order of ``world.pictures.CATEGORIES``.
CATEGORY_RGB = tuple(palette.rgb(palette.category(c)) for c in range(len(CATEGORIES)))
#: What the legend strip names, in its order.
LEGEND = (
    *zip(CATEGORIES, CATEGORY_RGB),
    ("start", START_RGB),
    ("goal", GOAL_RGB),
    ("A_d", UNSAFE_RGB),
    ("robot", ROBOT_RGB),
)
LINE = 12  # pixels per line of the legend strip


def _disc(tile: int, rx: float, ry: float) -> np.ndarray:
    """Boolean (tile, tile) mask of an ellipse centred in the tile with radii ``rx``, ``ry`` (in tiles)."""
    c = (np.arange(tile) + 0.5) / tile - 0.5
    return (c[None, :] / rx) ** 2 + (c[:, None] / ry) ** 2 <= 1.0


def rgb_frame(
    layout: Layout, categories: np.ndarray, unsafe: np.ndarray, robot: int, tile: int = 32
) -> np.ndarray:
    """The maze seen from above, ``(height * tile + legend height, width * tile, 3)`` uint8: the
    maze on top, the legend strip (:func:`legend_strip`) below.

    ``categories[o]`` is the category of obstacle ``o`` (the order of ``layout.obstacles``),
    ``unsafe`` the (n_cells, 4) A_d, ``robot`` the robot's cell; ``tile`` 8 pixels or more (the
    environment's check of ``tile_size``)."""
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
    return np.concatenate([img, legend_strip(w * tile)])


def legend_strip(width: int) -> np.ndarray:
    """The legend under the maze, ``width`` pixels wide: a swatch and a name per colour of
    :data:`LEGEND`, as many to a line as fit (PIL's built-in bitmap font)."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=10)
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    lines, x = [[]], 0.0
    for name, colour in LEGEND:
        w = 14 + probe.textlength(name, font=font) + 8  # swatch, name, gap
        if x + w > width and lines[-1]:
            lines.append([])
            x = 0.0
        lines[-1].append((name, colour, x))
        x += w
    strip = Image.new("RGB", (width, LINE * len(lines) + 4), FREE_RGB)
    draw = ImageDraw.Draw(strip)
    for i, line in enumerate(lines):
        y = 2 + LINE * i
        for name, colour, x0 in line:
            draw.rectangle([x0 + 2, y + 1, x0 + 11, y + 10], fill=colour, outline=GRID_RGB)
            draw.text((x0 + 14, y), name, fill=(0, 0, 0), font=font)
    return np.asarray(strip, dtype=np.uint8)


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
