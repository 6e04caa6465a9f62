"""A maze by name: a built-in layout (``conf/mazes/<name>.txt``, the paper's 5x5, 7x7 and
11x11 of section 4.1, Figures 6 and 11), a layout file, or a generated layout (``random:...``,
:mod:`pipeline.world.generate`).

The layouts themselves (:class:`Layout`, the text format, moves and shortest paths) are
:mod:`pipeline.world.layout`'s, which :mod:`pipeline.world.generate` builds on too; their names
are importable from here as well (``from pipeline.world.maze import Layout, load_layout``).
"""

from __future__ import annotations

from pathlib import Path

from pipeline.config.folder import conf_dir
from pipeline.world import generate
from pipeline.world.layout import (
    ACTION_NAMES,
    LAYOUT_CHARS,
    MOVES,
    N_ACTIONS,
    Layout,
    MazeError,
    bfs_distances,
    count_shortest_paths,
    parse_layout,
    shortest_path_length,
)

__all__ = [
    "ACTION_NAMES",
    "BUILTIN_DIR",
    "LAYOUT_CHARS",
    "MAX_LAYOUT_BYTES",
    "MOVES",
    "N_ACTIONS",
    "Layout",
    "MazeError",
    "bfs_distances",
    "count_shortest_paths",
    "load_layout",
    "parse_layout",
    "shortest_path_length",
]

#: The built-in layouts, one ``<name>.txt`` each.
BUILTIN_DIR = conf_dir("mazes")
#: Larger files are refused up front (a 1000x1000 layout is parsed and checked in about a second).
MAX_LAYOUT_BYTES = 4_100_000


def load_layout(spec: str | Path) -> Layout:
    """Load a layout by built-in name (``5x5``, ``7x7``, ``11x11``: files in
    ``conf/mazes/``), by path, or generate one from a
    ``random:<W>x<H>:<obstacles>:<seed>[:unique]`` name (:mod:`pipeline.world.generate`)."""
    if generate.is_spec(spec):
        return generate.generate_layout(spec)
    try:
        return _load_file(spec)
    except OSError as exc:  # a name over the file system's limit, a path through a file...
        raise MazeError(
            f"{spec}: cannot be opened as a layout file ({exc.strerror or exc})"
        ) from None


def _load_file(spec: str | Path) -> Layout:
    path = Path(spec)
    if not path.suffix and not path.exists():
        builtin = BUILTIN_DIR / f"{spec}.txt"
        if not builtin.exists():
            names = sorted(p.stem for p in BUILTIN_DIR.glob("*.txt"))
            raise MazeError(
                f"maze {str(spec)!r}: neither a file nor a built-in maze ({', '.join(names)})"
            )
        path = builtin
    if not path.exists():
        raise MazeError(f"{path}: maze file not found")
    if path.is_dir():
        raise MazeError(f"{path}: a folder, not a layout file")
    if not path.is_file():  # a pipe or a device: reading it could block or never end
        raise MazeError(f"{path}: not a regular file (a pipe or a device), not a layout file")
    if path.stat().st_size > MAX_LAYOUT_BYTES:
        raise MazeError(
            f"{path}: {path.stat().st_size:,} bytes; layouts up to {MAX_LAYOUT_BYTES:,} bytes "
            "(about 2000 x 2000 cells) are accepted"
        )
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte order mark is not a cell
    except UnicodeDecodeError as exc:
        raise MazeError(f"{path}: not a text file ({exc.reason})") from None
    except OSError as exc:
        raise MazeError(f"{path}: cannot read ({exc.strerror})") from None
    return parse_layout(text, source=str(path))
