"""Fault suite: bad input and faults through the command line's entry (``pipeline.__main__.main``,
in this process; in a child process where a signal or a second process is the point). Every case
asserts the exit code, one line on stderr naming the thing and the problem, and that nothing
already on disk was lost (docs/reliability.md lists the guarantees)."""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import pytest
from entry import cli

ROOT = Path(__file__).resolve().parents[1]
FAST = ["runs=2", "episodes=4", "progress=false"]


def one_line_error(out, *words, code=2):
    assert out.returncode == code, (out.returncode, out.stderr[-2000:])
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def digest(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


# ------------------------------------------------------------------ layouts
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


# ------------------------------------------------------------------ configs and out folders
@pytest.mark.parametrize(
    "args,words",
    [
        (["runs=2.7"], ["config key 'runs'", "Integer"]),
        (["episodes=abc"], ["config key 'episodes'"]),
        (["record=maybe"], ["config key 'record'"]),
        (["threads=-1"], ["config key 'threads'", ">= 0"]),
        (["threads=999"], ["config key 'threads'", "at most"]),
        (["out="], ["config key 'out'", "empty"]),
        (["bogus=1"], ["config key 'bogus'"]),
        (["method=nope"], ["method/nope"]),
        (["runs=100", "episodes=100000000000000"], ["need about", "GiB", "available"]),
        (["out=/proc/version/x"], ["config key 'out'"]),
    ],
)
def test_bad_trial_configs(tmp_path, args, words):
    one_line_error(cli("trials", *args, "progress=false"), *words)


def test_record_none_means_no_records(tmp_path):
    assert cli("trials", "record=none", f"out={tmp_path}", *FAST).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_out_that_is_a_file_is_refused_and_kept(tmp_path):
    target = tmp_path / "results"
    target.write_text("mine")
    one_line_error(cli("trials", f"out={target}", *FAST), "config key 'out'", "is a file")
    assert target.read_text() == "mine"


def test_every_stage_turns_a_bad_config_into_one_line(tmp_path):
    one_line_error(cli("render", "size=abc"), "config key 'size'")
    one_line_error(cli("meta_train", "train.lr=-1"), "config key 'train.lr'")
    one_line_error(cli("accuracy", "study.repeats=0"), "config key 'study.repeats'")
    one_line_error(cli("report", "out="), "config key 'out'")
    one_line_error(
        cli("replay", f"file={tmp_path / 'none.mcap'}"), "config key 'file'", "no such record file"
    )
