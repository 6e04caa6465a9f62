"""Random maze layouts from a spec: ``random:<W>x<H>:<obstacles>:<seed>`` and ``...:unique``.

Wherever a maze is accepted (``maze=`` of the trials stage and of experiment cells, the ``maze``
keyword of the Gymnasium environment), :func:`pipeline.world.maze.load_layout` passes a name that
starts with ``random:`` here. The layout is ``W`` cells wide and ``H`` high, with the start in the
top-left corner and the goal in the bottom-right one (as in ``conf/mazes/``), exactly
``obstacles`` obstacles and the goal reachable:

* ``random:<W>x<H>:<obstacles>:<seed>`` (:func:`scatter`): the cells other than start and goal,
  in a random order, each become an obstacle unless that would leave no path from start to goal
  short enough to fit the free cells that must remain; this stops at ``obstacles``. It never
  fails for a feasible count (at most ``W*H - (W+H-1)``: a shortest path needs ``W+H-1`` free
  cells) and, for sparse grids, is close to drawing the obstacles uniformly among the layouts
  with a reachable goal.
* ``random:<W>x<H>:<obstacles>:<seed>:unique`` (:func:`lined_path`): the paper's kind of layout
  (``conf/mazes/5x5.txt``): a single shortest path from start to goal that runs between
  obstacles. A random monotone path (a shuffle of ``W-1`` moves east and ``H-1`` south) is drawn;
  obstacles on the free neighbours of the path ("lining" cells, in a random order) close every
  other path of the same length; the remaining obstacles go on the other lining cells first, then
  on the rest of the grid in a random order. So with at least as many obstacles as lining cells
  the path is lined on both sides, as in the paper's 5x5. If closing the other shortest paths
  takes more obstacles than the spec has, another path is drawn, up to :data:`UNIQUE_DRAWS` times.

The random numbers come from numpy's ``Generator`` (PCG64) seeded with
``[seed, W, H, obstacles, unique]``, so the same spec gives the same layout on every machine
with the locked numpy (``tests/test_generate.py`` pins one). The layout's name is the spec in
its canonical form (``random:5x5:9:1``); the trials stage records its rows like any other
layout's. A spec that cannot be met raises :class:`~pipeline.world.layout.MazeError` naming the
spec and the reason.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np

from pipeline.world.layout import MOVES, Layout, MazeError, bfs_distances, parse_layout

PREFIX = "random:"
SPEC_PATTERN = re.compile(r"random:(\d+)x(\d+):(\d+):(\d+)(:unique)?")
SPEC_FORM = "random:<W>x<H>:<obstacles>:<seed> or random:<W>x<H>:<obstacles>:<seed>:unique"
#: Largest width or height (a 100x100 layout is generated in well under a second).
MAX_SIDE = 100
#: Monotone paths tried for a ``unique`` layout before the spec is refused.
UNIQUE_DRAWS = 100
EAST, SOUTH = 1, 2


@dataclass(frozen=True)
class LayoutSpec:
    """What ``random:<W>x<H>:<obstacles>:<seed>[:unique]`` asks for."""

    width: int
    height: int
    obstacles: int
    seed: int
    unique: bool = False

    @property
    def name(self) -> str:
        """The spec in canonical form (no leading zeros): the layout's name in the records."""
        tail = ":unique" if self.unique else ""
        return f"{PREFIX}{self.width}x{self.height}:{self.obstacles}:{self.seed}{tail}"

    @property
    def max_obstacles(self) -> int:
        """Cells minus the ``W+H-1`` cells of a shortest start-goal path."""
        return self.width * self.height - (self.width + self.height - 1)


def is_spec(maze: object) -> bool:
    """Whether a maze name asks for a generated layout (starts with ``random:``)."""
    return isinstance(maze, str) and maze.startswith(PREFIX)


def parse_spec(text: str) -> LayoutSpec:
    """The :class:`LayoutSpec` of ``text``; :class:`MazeError` if malformed or impossible."""
    match = SPEC_PATTERN.fullmatch(text)
    if match is None:
        raise MazeError(
            f"maze {text!r}: malformed; expected {SPEC_FORM} (whole numbers), "
            "e.g. random:11x11:49:7:unique"
        )
    width, height, obstacles, seed = (int(g) for g in match.groups()[:4])
    spec = LayoutSpec(width, height, obstacles, seed, unique=match.group(5) is not None)
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE and width * height >= 2):
        raise MazeError(
            f"maze {text!r}: a {width}x{height} grid; width and height must be 1 to "
            f"{MAX_SIDE} with at least 2 cells (start and goal)"
        )
    if obstacles > spec.max_obstacles:
        raise MazeError(
            f"maze {text!r}: too many obstacles for the grid: a {width}x{height} grid holds at "
            f"most {spec.max_obstacles} with a path from start to goal ({width + height - 1} "
            f"free cells); got {obstacles}"
        )
    return spec


def monotone_path(width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """Cells of a random shortest path from the top-left to the bottom-right corner: the
    ``width-1`` moves east and ``height-1`` moves south in a random order."""
    moves = rng.permutation(np.array([EAST] * (width - 1) + [SOUTH] * (height - 1), dtype=np.int64))
    steps = np.array([MOVES[a][0] * width + MOVES[a][1] for a in moves], dtype=np.int64)
    return np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)


def lining(path: np.ndarray, width: int, height: int) -> np.ndarray:
    """The cells beside ``path`` (4-neighbours) that are not on it, in increasing order."""
    on_path = np.zeros(width * height, dtype=np.bool_)
    on_path[path] = True
    rows, cols = np.divmod(path, width)
    beside = np.zeros(width * height, dtype=np.bool_)
    for dr, dc in MOVES:
        ok = (rows + dr >= 0) & (rows + dr < height) & (cols + dc >= 0) & (cols + dc < width)
        beside[(rows[ok] + dr) * width + cols[ok] + dc] = True
    return np.flatnonzero(beside & ~on_path).astype(np.int64)


def scatter(spec: LayoutSpec, rng: np.random.Generator) -> np.ndarray:
    """Obstacle mask of a layout without the ``unique`` option (the module docstring's first kind).

    A cell is kept as an obstacle only if a start-goal path of at most ``W*H - obstacles - 1``
    moves remains; while fewer than ``obstacles`` are placed, the free cells off the current
    shortest path outnumber the ones still to place and none of them was refused before
    (distances only grow), so one pass over the cells always places them all."""
    w, h = spec.width, spec.height
    start, goal, bound = 0, w * h - 1, w * h - spec.obstacles - 1
    blocked = np.zeros(w * h, dtype=np.bool_)
    placed = 0
    for cell in rng.permutation(np.arange(1, w * h - 1, dtype=np.int64)):
        if placed == spec.obstacles:
            break
        blocked[cell] = True
        moves = bfs_distances(blocked, h, w, start)[goal]
        if 0 <= moves <= bound:
            placed += 1
        else:
            blocked[cell] = False
    assert placed == spec.obstacles, "scatter: one pass always places every obstacle"
    return blocked


def shortest_path_cells(blocked: np.ndarray, width: int, height: int) -> np.ndarray:
    """Mask of the cells on some shortest start-goal path (distance from start plus distance to
    goal equals the shortest length)."""
    from_start = bfs_distances(blocked, height, width, 0)
    to_goal = bfs_distances(blocked, height, width, width * height - 1)
    length = from_start[width * height - 1]
    return (from_start >= 0) & (to_goal >= 0) & (from_start + to_goal == length)


def lined_path(spec: LayoutSpec, rng: np.random.Generator) -> np.ndarray | None:
    """Obstacle mask of a ``unique`` layout around one random monotone path (the module
    docstring's second kind), or None if closing the other shortest paths takes more than
    ``spec.obstacles`` obstacles.

    Every other shortest path leaves the drawn one through a lining cell that lies on it, so the
    first cell in the order (lining cells first) that lies on another shortest path is a lining
    cell; blocking such cells one at a time ends when the drawn path is the only shortest one."""
    w, h = spec.width, spec.height
    path = monotone_path(w, h, rng)
    beside = lining(path, w, h)
    others = np.setdiff1d(np.arange(w * h, dtype=np.int64), np.concatenate([path, beside]))
    order = np.concatenate([rng.permutation(beside), rng.permutation(others)])
    on_path = np.zeros(w * h, dtype=np.bool_)
    on_path[path] = True
    blocked = np.zeros(w * h, dtype=np.bool_)
    while (other := shortest_path_cells(blocked, w, h) & ~on_path).any():
        blocked[order[np.argmax(other[order])]] = True
    if blocked.sum() > spec.obstacles:
        return None
    rest = order[~blocked[order]]
    blocked[rest[: spec.obstacles - int(blocked.sum())]] = True
    return blocked


def rows_of(blocked: np.ndarray, width: int, height: int) -> tuple[str, ...]:
    """The text rows of an obstacle mask, ``S`` top-left and ``G`` bottom-right."""
    chars = np.where(blocked, "X", ".").astype("<U1")
    chars[0], chars[-1] = "S", "G"
    return tuple("".join(chars[r * width : (r + 1) * width]) for r in range(height))


def generate(spec: LayoutSpec) -> Layout:
    """The layout of ``spec`` (module docstring), checked by the layout parser like a file."""
    rng = np.random.default_rng(
        [spec.seed, spec.width, spec.height, spec.obstacles, int(spec.unique)]
    )
    if spec.unique:
        blocked = next(
            (b for _ in range(UNIQUE_DRAWS) if (b := lined_path(spec, rng)) is not None), None
        )
        if blocked is None:
            raise MazeError(
                f"maze {spec.name!r}: no layout with a unique shortest path found in {UNIQUE_DRAWS} "
                f"draws: closing the other shortest paths took more than {spec.obstacles} obstacles "
                "each time; give more obstacles"
            )
    else:
        blocked = scatter(spec, rng)
    text = "\n".join(rows_of(blocked, spec.width, spec.height))
    return parse_layout(text, source=spec.name)


@functools.lru_cache(maxsize=4096)  # a study's methods share each layout: generated once
def generate_layout(text: str) -> Layout:
    """The layout a ``random:...`` maze name asks for; :class:`MazeError` if it cannot be made."""
    return generate(parse_spec(text))
