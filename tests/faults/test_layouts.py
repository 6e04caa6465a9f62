"""Hostile maze layout files (docs/reliability.md "Layouts"), derived from the built-in mazes
(``conf/mazes/*.txt``): every cell replaced by a character the grammar does not have, the
start or the goal removed or doubled, rows made ragged, the goal or the start walled in, a blank
line inside, other encodings and line ends, binary bytes, empty and huge files. A new built-in maze
gets its cases without an edit here.

Each case is one line naming the file (and its line and column where there is one): the whole
:class:`~pipeline.world.layout.MazeError` message is compared. A file that is a maze after all is
read as the same rows as the built-in one: a UTF-8 byte order mark and CR LF or CR line ends (what
Windows editors write), trailing blanks, comment lines and blank lines at the end; any other line
separator (form feed, U+2028...) is an unknown character of its line. In-process
(:func:`~pipeline.world.maze.load_layout`); the trials stage for one maze's cases (the same line as
``config key 'maze'``, and no ``out`` folder; an accepted variant runs as the built-in maze does),
and the command line once (exit 2).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from entry import ROOT, cli

from faults._checks import FAST, one_line_error
from pipeline.errors import ConfigError
from pipeline.stages import run_stage
from pipeline.world.maze import BUILTIN_DIR, MAX_LAYOUT_BYTES, MazeError, load_layout

MAZES = {p.stem: p.read_text(encoding="utf-8") for p in sorted(BUILTIN_DIR.glob("*.txt"))}
ROWS = {name: text.split("\n")[:-1] for name, text in MAZES.items()}
#: Characters the grammar does not have: letters of other cases, digits, look-alikes (a full-width
#: X, a zero-width space, a no-break space), control characters, separators and blanks.
BAD = [
    "a",
    "s",
    "g",
    "x",
    "0",
    "*",
    "Ｘ",
    "\u200b",
    "\xa0",
    "\x00",
    "\x7f",
    "é",
    "\t",
    " ",
    "\x0c",
    "\u2028",
    "#",
]
BLANK = {ch for ch in BAD if ch.isspace()}
RUN = ["runs=2", "episodes=4", "progress=false", "record=none", "method=ssrl"]


def bad_char(rows: list[str], r: int, c: int) -> str:
    """The character that replaces cell (r, c): the list in turn, but no blank in the last column
    (trailing blanks are ignored: a ragged row, another case) and no ``#`` in the first (a comment)."""
    k = r * len(rows[0]) + c
    allowed = [
        ch
        for ch in BAD
        if not (c == len(rows[0]) - 1 and ch in BLANK) and not (c == 0 and ch == "#")
    ]
    return allowed[k % len(allowed)]


def with_cell(rows: list[str], r: int, c: int, ch: str) -> list[str]:
    out = list(rows)
    out[r] = out[r][:c] + ch + out[r][c + 1 :]
    return out


def find(rows: list[str], ch: str) -> tuple[int, int]:
    r = next(i for i, row in enumerate(rows) if ch in row)
    return r, rows[r].index(ch)


def free(rows: list[str], last: bool = False) -> tuple[int, int]:
    cells = [(r, c) for r, row in enumerate(rows) for c, x in enumerate(row) if x == "."]
    return cells[-1] if last else cells[0]


def walled(rows: list[str], ch: str) -> list[str]:
    """``ch``'s four neighbours made obstacles."""
    r0, c0 = find(rows, ch)
    out = list(rows)
    for r, c in ((r0 - 1, c0), (r0 + 1, c0), (r0, c0 - 1), (r0, c0 + 1)):
        if 0 <= r < len(rows) and 0 <= c < len(rows[0]) and rows[r][c] == ".":
            out = with_cell(out, r, c, "X")
    return out


def text(rows: list[str]) -> str:
    return "\n".join(rows) + "\n"


def refused(path: Path, expected: str) -> None:
    with pytest.raises(MazeError) as err:
        load_layout(path)
    message = str(err.value)
    assert "\n" not in message and message == expected, message


# ------------------------------------------------------------------ every cell, a bad character
CELLS = [
    pytest.param(name, r, c, id=f"{name}-{r + 1}:{c + 1}-{bad_char(rows, r, c)!r}")
    for name, rows in ROWS.items()
    for r in range(len(rows))
    for c in range(len(rows[0]))
]


@pytest.mark.parametrize("name,r,c", CELLS)
def test_a_cell_replaced_by_a_bad_character_is_named_by_line_and_column(tmp_path, name, r, c):
    rows = ROWS[name]
    ch = bad_char(rows, r, c)
    path = tmp_path / f"{name}.txt"
    path.write_text(text(with_cell(rows, r, c, ch)), encoding="utf-8")
    refused(path, f"{path}:{r + 1}:{c + 1}: unknown character {ch!r} (allowed: S G X .)")


# ------------------------------------------------------------------ the grammar's other rules
def mutations(rows: list[str]) -> dict[str, tuple[str, str]]:
    """Mutation -> (file text, the message after ``<path>``), derived from the maze's rows."""
    h, w = len(rows), len(rows[0])
    s, g, first, last = find(rows, "S"), find(rows, "G"), free(rows), free(rows, last=True)
    mid = h // 2
    letter = next((r, c) for r, row in enumerate(rows) for c, x in enumerate(row) if x != ".")
    unreachable = f":{g[0] + 1}:{g[1] + 1}: the goal is unreachable from the start"

    def at(*cells):
        return ", ".join(f"line {r + 1} column {c + 1}" for r, c in sorted(cells))

    return {
        "no start": (text(with_cell(rows, *s, ".")), ": no start cell 'S'"),
        "no goal": (text(with_cell(rows, *g, ".")), ": no goal cell 'G'"),
        "two starts": (
            text(with_cell(rows, *first, "S")),
            f": 2 start cells 'S' (at {at(s, first)}); exactly one allowed",
        ),
        "two goals": (
            text(with_cell(rows, *last, "G")),
            f": 2 goal cells 'G' (at {at(g, last)}); exactly one allowed",
        ),
        "a short row": (
            text(rows[:mid] + [rows[mid][:-1]] + rows[mid + 1 :]),
            f":{mid + 1}: ragged row: {w - 1} cells where line 1 has {w}",
        ),
        "a long row": (
            text(rows[:mid] + [rows[mid] + "X"] + rows[mid + 1 :]),
            f":{mid + 1}: ragged row: {w + 1} cells where line 1 has {w}",
        ),
        "the goal walled in": (text(walled(rows, "G")), unreachable),
        "the start walled in": (text(walled(rows, "S")), unreachable),
        "a blank line inside": (
            text(rows[:mid] + [""] + rows[mid:]),
            f":{mid + 1}: blank line inside the layout",
        ),
        "a line of blanks inside": (
            text(rows[:mid] + ["   \t"] + rows[mid:]),
            f":{mid + 1}: blank line inside the layout",
        ),
        "empty": ("", ": empty layout (expected rows of S, G, X and .)"),
        "only comments and blank lines": (
            "# a maze\n\n   \n# was here\n",
            ": empty layout (expected rows of S, G, X and .)",
        ),
        "form feeds for line ends": (
            text(rows).replace("\n", "\f", 1),
            f":1:{w + 1}: unknown character '\\x0c' (allowed: S G X .)",
        ),
        "U+2028 for line ends": (
            text(rows).replace("\n", "\u2028", 1),
            f":1:{w + 1}: unknown character '\\u2028' (allowed: S G X .)",
        ),
        "NUL bytes": ("\0" * w + "\n", ":1:1: unknown character '\\x00' (allowed: S G X .)"),
        "two byte order marks": (
            "\ufeff\ufeff" + text(rows),
            ":1:1: unknown character '\\ufeff' (allowed: S G X .)",
        ),
        "a lower-case maze": (
            text(rows).lower(),
            f":{letter[0] + 1}:{letter[1] + 1}: unknown character "
            f"{rows[letter[0]][letter[1]].lower()!r} (allowed: S G X .)",
        ),
    }


GRAMMAR = [
    pytest.param(name, what, id=f"{name}-{what}")
    for name, rows in ROWS.items()
    for what in mutations(rows)
]


@pytest.mark.parametrize("name,what", GRAMMAR)
def test_a_layout_against_the_grammar_is_one_line(tmp_path, name, what):
    body, problem = mutations(ROWS[name])[what]
    path = tmp_path / f"{name}.txt"
    path.write_text(body, encoding="utf-8", newline="")
    refused(path, f"{path}{problem}")


# ------------------------------------------------------------------ bytes and files
def encodings(rows: list[str]) -> dict[str, bytes]:
    """Files that are not UTF-8 text: refused as ``not a text file``."""
    body = text(rows)
    return {
        "UTF-16": body.encode("utf-16"),
        "UTF-32": body.encode("utf-32"),
        "Latin-1 with an accent": ("é" + body).encode("latin-1"),
        "PNG bytes": b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR" + bytes(range(256)),
        "random bytes": bytes((i * 151 + 7) % 256 for i in range(4096)),
        "a cut multi-byte character": body.encode() + "é".encode()[:1],
    }


@pytest.mark.parametrize(
    "name,what", [(n, w) for n in ROWS for w in encodings(ROWS[n])], ids=lambda x: str(x)
)
def test_a_file_that_is_not_utf8_text_is_one_line(tmp_path, name, what):
    path = tmp_path / f"{name}.txt"
    path.write_bytes(encodings(ROWS[name])[what])
    with pytest.raises(MazeError) as err:
        load_layout(path)
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{path}: not a text file ("), message


def accepted(rows: list[str]) -> dict[str, bytes]:
    """Files that are the maze after all (a byte order mark, CR LF or CR line ends, trailing
    blanks, comments, blank lines at the end, no final line end)."""
    body = text(rows)
    return {
        "byte order mark": b"\xef\xbb\xbf" + body.encode(),
        "CR LF": body.replace("\n", "\r\n").encode(),
        "CR": body.replace("\n", "\r").encode(),
        "byte order mark and CR LF": b"\xef\xbb\xbf" + body.replace("\n", "\r\n").encode(),
        "mixed line ends": body.replace("\n", "\r\n", len(rows) // 2).encode(),
        "trailing blanks": body.replace("\n", " \t \n").encode(),
        "comments": ("# a comment\n" + body.replace("\n", "\n  # another\n", 1)).encode(),
        "blank lines at the end": (body + "\n\n   \n").encode(),
        "no final line end": body.rstrip("\n").encode(),
    }


@pytest.mark.parametrize(
    "name,what", [(n, w) for n in ROWS for w in accepted(ROWS[n])], ids=lambda x: str(x)
)
def test_a_variant_that_is_the_maze_reads_as_the_maze(tmp_path, name, what):
    path = tmp_path / f"{name}.txt"
    path.write_bytes(accepted(ROWS[name])[what])
    assert load_layout(path).rows == load_layout(name).rows == tuple(ROWS[name])


def test_files_that_are_no_layout_are_one_line(tmp_path):
    """A missing file, a folder, a pipe, a device, a name over the file system's limit, a path
    through a file, a symbolic link loop, a file over the size limit (sparse: nothing is read)."""
    (tmp_path / "folder.txt").mkdir()
    os.mkfifo(tmp_path / "pipe.txt")
    (tmp_path / "loop.txt").symlink_to(tmp_path / "loop.txt")
    (tmp_path / "file.txt").write_text("SG\n")
    huge = tmp_path / "huge.txt"
    with open(huge, "wb") as f:
        f.truncate(MAX_LAYOUT_BYTES + 1)
    long = "m" * 5000 + ".txt"
    cases = {
        tmp_path / "missing.txt": f"{tmp_path / 'missing.txt'}: maze file not found",
        tmp_path / "folder.txt": f"{tmp_path / 'folder.txt'}: a folder, not a layout file",
        tmp_path
        / "pipe.txt": f"{tmp_path / 'pipe.txt'}: not a regular file (a pipe or a device), not a layout file",
        Path("/dev/zero"): "/dev/zero: not a regular file (a pipe or a device), not a layout file",
        tmp_path / "loop.txt": f"{tmp_path / 'loop.txt'}: maze file not found",
        tmp_path / "file.txt" / "m.txt": f"{tmp_path / 'file.txt' / 'm.txt'}: maze file not found",
        huge: f"{huge}: {MAX_LAYOUT_BYTES + 1:,} bytes; layouts up to {MAX_LAYOUT_BYTES:,} bytes (about 2000 x 2000 cells) are accepted",
        tmp_path
        / long: f"{tmp_path / long}: cannot be opened as a layout file (File name too long)",
        "nosuchmaze": "maze 'nosuchmaze': neither a file nor a built-in maze ("
        + ", ".join(sorted(ROWS))
        + ")",
    }
    for spec, expected in cases.items():
        refused(spec, expected)


# ------------------------------------------------------------------ through the trials stage
FIRST = next(iter(ROWS))


@pytest.mark.parametrize("what", list(mutations(ROWS[FIRST]))[:8])
def test_the_trials_stage_refuses_a_bad_layout_before_any_folder(tmp_path, what):
    body, problem = mutations(ROWS[FIRST])[what]
    path = tmp_path / "maze.txt"
    path.write_text(body, encoding="utf-8", newline="")
    with pytest.raises(ConfigError) as err:
        run_stage("trials", [f"maze={path}", f"out={tmp_path / 'o'}", *RUN])
    assert str(err.value) == f"config key 'maze': {path}{problem}"
    assert not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def builtin_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("builtin") / "o"
    run_stage("trials", [f"maze={FIRST}", f"out={out}", *RUN])
    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("what", ["byte order mark and CR LF", "CR", "comments"])
def test_an_accepted_variant_runs_as_the_builtin_maze(tmp_path, builtin_run, what):
    path = tmp_path / f"{FIRST}.txt"
    path.write_bytes(accepted(ROWS[FIRST])[what])
    run_stage("trials", [f"maze={path}", f"out={tmp_path / 'o'}", *RUN])
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["collisions"] == builtin_run["collisions"]
    assert summary["n_runs"] == builtin_run["n_runs"] == 2


def test_the_command_line_says_one_line_and_exits_2(tmp_path):
    body, problem = mutations(ROWS[FIRST])["the goal walled in"]
    path = tmp_path / "maze.txt"
    path.write_text(body)
    out = subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", f"maze={path}", f"out={tmp_path / 'o'}", *RUN],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2 and out.stdout == "", out.stderr
    assert out.stderr == f"error: config key 'maze': {path}{problem}\n"
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------- through the command line
@pytest.mark.parametrize(
    "text,words",
    [
        ("", ["empty layout"]),
        ("S..\n..\n..G\n", ["ragged row"]),
        ("S.a\n...\n..G\n", ["unknown character 'a'"]),
        ("...\n...\n..G\n", ["no start"]),
        ("S.G\n...\n..G\n", ["2 goal cells"]),
        ("S.X\n.X.\nX.G\n", ["unreachable"]),
        ("S..\n\n..G\n", ["blank line"]),
    ],
)
def test_bad_layouts(tmp_path, text, words):
    layout = tmp_path / "maze.txt"
    layout.write_text(text)
    one_line_error(
        cli("trials", f"maze={layout}", f"out={tmp_path / 'o'}", *FAST),
        "config key 'maze'",
        str(layout),
        *words,
    )
    assert not (tmp_path / "o").exists()


def test_layout_folder_binary_and_oversized(tmp_path):
    one_line_error(
        cli("trials", f"maze={tmp_path}", f"out={tmp_path / 'o'}"), "a folder, not a layout file"
    )
    binary = tmp_path / "b.txt"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    one_line_error(cli("trials", f"maze={binary}", f"out={tmp_path / 'o'}"), "not a text file")
    huge = tmp_path / "huge.txt"
    huge.write_text(("." * 2999 + "\n") * 1500)
    one_line_error(cli("trials", f"maze={huge}", f"out={tmp_path / 'o'}"), "layouts up to")


@pytest.mark.parametrize("text", ["SG\n", "S..\n...\n..G\n", "S\nG\n"])
@pytest.mark.parametrize("method", ["ssrl", "fewshot_dss", "sarsa", "constrained"])
def test_unusual_valid_layouts_run(tmp_path, text, method):
    layout = tmp_path / "tiny.txt"
    layout.write_text(text)
    out = cli(
        "trials",
        f"maze={layout}",
        f"method={method}",
        f"out={tmp_path / 'o'}",
        *FAST,
        *(["recogniser=oracle"] if method == "fewshot_dss" else []),
    )
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["n_runs"] == 2


def test_a_1000x1000_layout_is_parsed_and_checked_in_seconds(tmp_path):
    import numpy as np

    from pipeline.world.geometry import build_geometry
    from pipeline.world.maze import load_layout

    grid = np.full((1000, 1000), ".")
    rng = np.random.default_rng(0)
    grid[rng.integers(1000, size=40000), rng.integers(1000, size=40000)] = "X"
    grid[0, 0], grid[-1, -1] = "S", "G"
    grid[0, 1:] = grid[:, -1] = "."
    grid[-1, -1] = "G"
    path = tmp_path / "big.txt"
    path.write_text("\n".join("".join(r) for r in grid) + "\n")
    load_layout(path)  # numba's first compile is not what we time
    t0 = time.perf_counter()
    layout = load_layout(path)
    build_geometry(layout)
    assert time.perf_counter() - t0 < 5.0
    assert layout.n_cells == 1_000_000
