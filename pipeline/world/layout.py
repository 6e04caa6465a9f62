"""Maze layouts as plain text (paper section 4.1, Figures 6 and 11): the grid world, its moves
and shortest paths, and the text format's parser.

One row per line: ``S`` start, ``G`` goal, ``X`` obstacle, ``.`` free. Blank lines at the end of
the text and trailing whitespace are ignored; ``#`` starts a comment line. Lines end in LF, CR LF
or CR (and a file loaded by :func:`pipeline.world.maze.load_layout` may start with a UTF-8 byte
order mark, as Windows editors write it); any other character, other line separators such as form
feed or U+2028 included, is an unknown character of its line. Cells are numbered
``row * width + col``; actions are 0 N, 1 E, 2 S, 3 W, one cell a step.

Both ways to get a layout build on this module: :mod:`pipeline.world.maze` loads one by name or
from a file, :mod:`pipeline.world.generate` makes one from a ``random:...`` spec.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numba as nb
import numpy as np

from pipeline.errors import UserError

#: Action -> (d_row, d_col). 0 N, 1 E, 2 S, 3 W (the order of ``pictures.FACE_NAMES``).
MOVES: tuple[tuple[int, int], ...] = ((-1, 0), (0, 1), (1, 0), (0, -1))
ACTION_NAMES: tuple[str, ...] = ("N", "E", "S", "W")
N_ACTIONS = 4


LAYOUT_CHARS = frozenset("SGX.")


class MazeError(UserError):
    """A layout file that cannot be a maze; the message names the file, line and problem."""


@dataclass(frozen=True)
class Layout:
    """A rectangular grid world. ``obstacles`` are cell indices in row-major order."""

    rows: tuple[str, ...]
    source: str = "<string>"

    @property
    def height(self) -> int:
        return len(self.rows)

    @property
    def width(self) -> int:
        return len(self.rows[0])

    @property
    def n_cells(self) -> int:
        return self.height * self.width

    @cached_property
    def _chars(self) -> np.ndarray:
        return np.frombuffer("".join(self.rows).encode("ascii", "replace"), dtype=np.uint8)

    def _find(self, ch: str) -> list[int]:
        return np.flatnonzero(self._chars == ord(ch)).tolist()

    @cached_property
    def start(self) -> int:
        return self._find("S")[0]

    @cached_property
    def goal(self) -> int:
        return self._find("G")[0]

    @cached_property
    def obstacles(self) -> tuple[int, ...]:
        return tuple(self._find("X"))

    @property
    def name(self) -> str:
        return (
            Path(self.source).stem if self.source != "<string>" else f"{self.height}x{self.width}"
        )

    def is_obstacle(self) -> np.ndarray:
        """Boolean mask over cells."""
        return self._chars == ord("X")

    def cell(self, index: int) -> tuple[int, int]:
        return divmod(index, self.width)

    def text(self) -> str:
        return "\n".join(self.rows) + "\n"


def _neighbour(layout_h: int, layout_w: int, cell: int, action: int) -> int | None:
    r, c = divmod(cell, layout_w)
    dr, dc = MOVES[action]
    r2, c2 = r + dr, c + dc
    if 0 <= r2 < layout_h and 0 <= c2 < layout_w:
        return r2 * layout_w + c2
    return None


@nb.njit(cache=True)
def bfs_distances(blocked: np.ndarray, h: int, w: int, source: int) -> np.ndarray:
    """Moves from ``source`` to every cell around the ``blocked`` cells (-1 where unreachable):
    breadth-first search over the 4-neighbourhood, O(cells)."""
    dist = np.full(h * w, -1, dtype=np.int64)
    queue = np.empty(h * w, dtype=np.int64)
    dist[source] = 0
    queue[0] = source
    head, tail = 0, 1
    while head < tail:
        s = queue[head]
        head += 1
        r, c = s // w, s % w
        for a in range(4):
            if a == 0:
                n = s - w if r > 0 else -1
            elif a == 1:
                n = s + 1 if c < w - 1 else -1
            elif a == 2:
                n = s + w if r < h - 1 else -1
            else:
                n = s - 1 if c > 0 else -1
            if n >= 0 and not blocked[n] and dist[n] < 0:
                dist[n] = dist[s] + 1
                queue[tail] = n
                tail += 1
    return dist


def shortest_path_length(layout: Layout) -> int | None:
    """Breadth-first search from start to goal around obstacles; None if the goal is unreachable."""
    n = int(
        bfs_distances(layout.is_obstacle(), layout.height, layout.width, layout.start)[layout.goal]
    )
    return None if n < 0 else n


def count_shortest_paths(layout: Layout) -> int:
    """Number of distinct shortest start->goal paths (0 if unreachable)."""
    blocked = layout.is_obstacle().tolist()
    dist = {layout.start: 0}
    ways = {layout.start: 1}
    queue = deque([layout.start])
    while queue:
        s = queue.popleft()
        for a in range(N_ACTIONS):
            n = _neighbour(layout.height, layout.width, s, a)
            if n is None or blocked[n]:
                continue
            if n not in dist:
                dist[n] = dist[s] + 1
                ways[n] = ways[s]
                queue.append(n)
            elif dist[n] == dist[s] + 1:
                ways[n] += ways[s]
    return ways.get(layout.goal, 0)


def parse_layout(text: str, source: str = "<string>") -> Layout:
    """Parse and validate a layout; raise :class:`MazeError` naming ``source``, the line and the problem."""
    rows: list[str] = []
    line_numbers: list[int] = []
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    for number, raw in enumerate(lines, start=1):
        line = raw.rstrip()
        if line.lstrip().startswith("#"):
            continue
        if not line:
            if rows:
                rows.append("")
                line_numbers.append(number)
            continue
        rows.append(line)
        line_numbers.append(number)
    while rows and rows[-1] == "":
        rows.pop()
        line_numbers.pop()
    if not rows:
        raise MazeError(f"{source}: empty layout (expected rows of S, G, X and .)")
    width = len(rows[0])
    counts = {"S": [], "G": []}
    for row, number in zip(rows, line_numbers):
        if not row:
            raise MazeError(f"{source}:{number}: blank line inside the layout")
        if len(row) != width:
            raise MazeError(
                f"{source}:{number}: ragged row: {len(row)} cells where line {line_numbers[0]} has {width}"
            )
        if not set(row) <= LAYOUT_CHARS:
            col, ch = next(
                (col, ch) for col, ch in enumerate(row, start=1) if ch not in LAYOUT_CHARS
            )
            raise MazeError(f"{source}:{number}:{col}: unknown character {ch!r} (allowed: S G X .)")
        for ch in counts:
            if ch in row:
                counts[ch] += [
                    f"line {number} column {col}" for col, x in enumerate(row, start=1) if x == ch
                ]
    for ch, what in (("S", "start"), ("G", "goal")):
        if not counts[ch]:
            raise MazeError(f"{source}: no {what} cell {ch!r}")
        if len(counts[ch]) > 1:
            raise MazeError(
                f"{source}: {len(counts[ch])} {what} cells {ch!r} (at {', '.join(counts[ch])}); exactly one allowed"
            )
    layout = Layout(rows=tuple(rows), source=source)
    if shortest_path_length(layout) is None:
        r, c = layout.cell(layout.goal)
        raise MazeError(
            f"{source}:{line_numbers[r]}:{c + 1}: the goal is unreachable from the start"
        )
    return layout
