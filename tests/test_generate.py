"""Generated layouts (``maze=random:<W>x<H>:<obstacles>:<seed>[:unique]``, pipeline/world/generate.py):
the same spec gives the same layout, exactly the obstacles asked for, a reachable goal, a unique
lined shortest path when asked; impossible specs are refused naming the key ``maze``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fakes import FIG8_WITHOUT_MODELS

from pipeline.config.compose import load_config
from pipeline.errors import ConfigError
from pipeline.stages import run_stage
from pipeline.stages.trials import resolve_cells
from pipeline.world.generate import (
    UNIQUE_DRAWS,
    generate_layout,
    lining,
    parse_spec,
    shortest_path_cells,
)
from pipeline.world.maze import (
    MazeError,
    bfs_distances,
    count_shortest_paths,
    load_layout,
    shortest_path_length,
)

ROOT = Path(__file__).resolve().parents[1]
SPECS = [
    "random:5x5:9:1",
    "random:7x7:16:3",
    "random:11x11:49:7",
    "random:9x4:12:0",
    "random:3x8:0:5",
    "random:5x5:16:2",
    "random:20x15:150:11",
]
UNIQUE = [
    "random:5x5:9:1:unique",
    "random:7x7:16:3:unique",
    "random:11x11:49:7:unique",
    "random:9x4:5:0:unique",
    "random:11x11:20:4:unique",
    "random:5x5:16:2:unique",
    "random:2x2:1:0:unique",
]


def test_the_same_spec_gives_the_same_layout():
    """Pinned: a change of the generator (or of numpy's Generator stream) shows here."""
    assert load_layout("random:5x5:9:1:unique").rows == (
        "SXX..",
        "...X.",
        "XX..X",
        "..X.X",
        "..X.G",
    )
    assert load_layout("random:7x7:16:3").rows == (
        "S.X.X.X",
        ".X....X",
        ".X..X..",
        "..XX.XX",
        "X..X...",
        ".....X.",
        "...XX.G",
    )
    assert generate_layout("random:11x11:49:7:unique") == generate_layout(
        "random:11x11:49:7:unique"
    )
    assert load_layout("random:11x11:49:7").rows != load_layout("random:11x11:49:8").rows


@pytest.mark.parametrize("spec", SPECS + UNIQUE)
def test_corners_obstacle_count_and_a_reachable_goal(spec):
    layout = load_layout(spec)
    s = parse_spec(spec)
    assert (layout.width, layout.height) == (s.width, s.height)
    assert layout.start == 0 and layout.goal == layout.n_cells - 1
    assert len(layout.obstacles) == s.obstacles
    assert shortest_path_length(layout) is not None
    assert layout.name == spec


@pytest.mark.parametrize("spec", UNIQUE)
def test_unique_gives_one_shortest_path_lined_by_obstacles(spec):
    layout = load_layout(spec)
    assert count_shortest_paths(layout) == 1
    assert shortest_path_length(layout) == layout.width + layout.height - 2
    blocked = layout.is_obstacle()
    path = np.flatnonzero(shortest_path_cells(blocked, layout.width, layout.height))
    beside = lining(path, layout.width, layout.height)
    lined = int(blocked[beside].sum())
    assert lined == min(len(beside), len(layout.obstacles))  # obstacles go beside the path first
    if len(layout.obstacles) >= len(beside):  # the paper's 5x5: the path is a corridor
        reachable = bfs_distances(blocked, layout.height, layout.width, layout.start) >= 0
        assert reachable.sum() == len(path)


def test_the_densest_layouts_are_made():
    for spec in ("random:6x4:15:3", "random:6x4:15:3:unique"):
        layout = load_layout(spec)
        assert len(layout.obstacles) == 15 and count_shortest_paths(layout) == 1


@pytest.mark.parametrize(
    "spec,problem",
    [
        ("random:5x5:9", "malformed; expected random:<W>x<H>:<obstacles>:<seed>"),
        ("random:5x5:9:1:uniq", "malformed"),
        ("random:5by5:9:1", "malformed"),
        ("random:5x5:-1:1", "malformed"),
        ("random:", "malformed"),
        ("random:5x5:17:1", "too many obstacles for the grid: a 5x5 grid holds at most 16"),
        ("random:5x5:17:1:unique", "too many obstacles for the grid"),
        ("random:1x1:0:1", "a 1x1 grid; width and height must be 1 to 100 with at least 2 cells"),
        ("random:0x5:0:1", "a 0x5 grid"),
        ("random:101x5:0:1", "a 101x5 grid"),
        (
            "random:5x5:2:1:unique",
            f"no layout with a unique shortest path found in {UNIQUE_DRAWS} draws",
        ),
    ],
)
def test_impossible_specs_are_refused(spec, problem):
    with pytest.raises(MazeError) as err:
        load_layout(spec)
    message = str(err.value)
    assert message.startswith(f"maze {spec!r}: ") and problem in message and "\n" not in message


def test_an_experiment_cell_takes_a_generated_maze():
    args = [
        "+experiment=fig8",
        "maze=random:6x6:10:4",
        "recogniser=oracle",
        "profile=smoke",
        *FIG8_WITHOUT_MODELS,
    ]
    cells = resolve_cells(load_config("trials", args), args)
    assert {c.layout.rows for c in cells} == {load_layout("random:6x6:10:4").rows}
    with pytest.raises(
        ConfigError, match=r"^config key '.*maze': maze 'random:6x6:40:4': too many"
    ):
        bad = [
            "+experiment=fig8",
            "maze=random:6x6:40:4",
            "recogniser=oracle",
            *FIG8_WITHOUT_MODELS,
        ]
        resolve_cells(load_config("trials", bad), bad)


def test_the_gym_environment_takes_a_generated_maze():
    import gymnasium

    import pipeline  # noqa: F401  (registers the ids)

    env = gymnasium.make("SafeNav-v0", maze="random:6x4:5:2:unique")
    assert env.unwrapped.layout.rows == load_layout("random:6x4:5:2:unique").rows
    env.close()


def test_trials_record_the_generated_layout(tmp_path):
    """End to end at smoke scale, on the command line; the records hold the layout's rows."""
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "trials",
            "maze=random:5x5:9:1",
            "method=shield",
            "profile=smoke",
            f"out={tmp_path}",
            "progress=false",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["maze"] == "random:5x5:9:1"
    from pipeline.records import read_records

    meta = read_records(tmp_path / "records.mcap", pictures=False).meta
    assert meta.maze["layout"] == list(load_layout("random:5x5:9:1").rows)
    assert meta.maze["name"] == meta.info["info"]["maze"] == meta.config["maze"] == "random:5x5:9:1"
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "trials",
            "maze=random:5x5:30:1",
            f"out={tmp_path / 'bad'}",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert bad.stderr.startswith(
        "error: config key 'maze': maze 'random:5x5:30:1': too many obstacles"
    )
    assert not (tmp_path / "bad").exists()


def test_run_stage_refuses_a_malformed_spec(tmp_path):
    with pytest.raises(ConfigError, match=r"^config key 'maze': maze 'random:5x5': malformed"):
        run_stage("trials", ["maze=random:5x5", f"out={tmp_path}", "progress=false"])
