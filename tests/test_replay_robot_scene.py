"""What the robot's 3D replay shows (pipeline.replay.robot3d, .scene3d): 2D content in the 3D space
only under the camera's pinhole, views set up by the blueprint with the whole maze in the opening
eye, the robot's body and heading, its path so far, collisions and stops marked, a legend in the
palette's colours, and the events on the step timeline with their levels."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from test_replay_robot import _chunks, _path, _seconds, cell  # noqa: F401 (cell: a fixture)

from pipeline import palette
from pipeline.records import read_records
from pipeline.records import schema as S
from pipeline.replay import build_replay
from pipeline.replay.robot3d import MARK_HEIGHT, STOP_AHEAD, STOP_RADIUS
from pipeline.replay.scene3d import (
    FIT_FOV,
    LEGEND_TEXT,
    MARGIN,
    MARKS,
    corners,
    legend_positions,
    overview_eye,
)
from pipeline.stages.replay import WORLDS

TWO_D = ("EncodedImage:", "Image:", "Points2D:", "Boxes2D:", "LineStrips2D:", "Arrows2D:")


@pytest.fixture(scope="module")
def replay(cell, tmp_path_factory):  # noqa: F811
    """Episode 0 of the tiny robot cell replayed, with its records."""
    rrd = build_replay(cell, 0, 0, out=tmp_path_factory.mktemp("r") / "r.rrd", worlds=WORLDS)
    return rrd, read_records(cell)


def _components(rrd, store=None) -> dict[str, dict[str, list]]:
    """Entity -> column -> the values of every row (static and temporal, in file order)."""
    import rerun.chunk

    out: dict[str, dict[str, list]] = {}
    for ch in rerun.chunk.RrdReader(rrd).stream(store=store).to_chunks():
        for k, v in ch.to_record_batch().to_pydict().items():
            out.setdefault(str(ch.entity_path), {}).setdefault(k, []).extend(v)
    return out


def _views(rrd) -> dict[tuple[str, str], dict[str, list]]:
    """(view class, origin) -> the view's blueprint columns (with its own parts: eye, contents)."""
    import rerun.chunk

    reader = rerun.chunk.RrdReader(rrd)
    parts = _components(rrd, store=reader.blueprints()[0])
    views = {}
    for entity, columns in parts.items():
        if "ViewBlueprint:class_identifier" in columns:
            merged = {k: v for e, c in parts.items() if e.startswith(entity) for k, v in c.items()}
            key = (
                columns["ViewBlueprint:class_identifier"][0][0],
                columns["ViewBlueprint:space_origin"][0][0],
            )
            views[key] = merged
    return views, parts


def test_in_the_3d_space_2d_content_lies_only_under_the_cameras_pinhole(replay):
    """No "2D visualizers require a pinhole ancestor": the live picture is the only 2D content under
    ``world``, and it lies under the camera's pinhole, which has the picture's size and field of view."""
    rrd, _ = replay
    parts = _components(rrd)
    two_d = sorted(
        e
        for e, c in parts.items()
        if e.startswith("/world") and any(k.startswith(TWO_D) for k in c)
    )
    pinholes = [e for e, c in parts.items() if "Pinhole:image_from_camera" in c]
    assert two_d == ["/world/robot/camera/image"] and pinholes == ["/world/robot/camera"]
    camera = parts["/world/robot/camera"]
    focal = 42 / math.tan(math.radians(48.8 / 2))  # 84 x 84 pixels, 48.8 degrees (the Pi camera's)
    assert np.allclose(
        camera["Pinhole:image_from_camera"][0], [focal, 0, 0, 0, focal, 0, 42, 42, 1]
    )
    assert camera["Pinhole:resolution"][0] == [[84, 84]]
    assert np.allclose(
        camera["Transform3D:translation"][0], [0.091, 0.0, 0.15]
    )  # on the robot's front


def test_the_blueprint_sets_up_every_view_and_opens_on_the_whole_maze(replay):
    rrd, recs = replay
    views, parts = _views(rrd)
    assert set(views) == {
        ("3D", "world"),
        ("TimeSeries", "metrics"),
        ("2D", "world/robot/camera"),  # the live picture, through the camera
        ("BarChart", "recognition/scores"),
        ("TextDocument", "recognition/result"),
        ("TextDocument", "legend"),
        ("2D", "support"),
        ("TextLog", "events"),
    }
    scene = views[("3D", "world")]
    assert scene["ViewContents:query"] == [["$origin/**", "- world/robot/camera/image/note"]]
    half = len(recs.meta.maze["layout"][0]) / 2  # 5 x 5 cells of 1 m
    rows = legend_positions(
        (-half, half), (-half, half), len(recs.meta.maze["categories"]) + len(MARKS)
    )
    position, target = overview_eye(  # the floor, its walls and the legend with its names
        (-half - MARGIN, rows[:, 0].max() + LEGEND_TEXT),
        (min(-half, rows[:, 1].min()) - MARGIN, half + MARGIN),
    )
    assert np.allclose(scene["EyeControls3D:position"][0], [position])
    assert np.allclose(scene["EyeControls3D:look_target"][0], [target])
    assert scene["EyeControls3D:eye_up"][0] == [[0.0, 0.0, 1.0]]
    assert parts["/time_panel"]["TimePanelBlueprint:timeline"] == [["sim_time"]]


@pytest.mark.parametrize("x_range, y_range", [((-2.7, 5.1), (-2.7, 2.7)), ((-1, 1), (-4, 9))])
def test_the_opening_eye_sees_every_corner_of_the_floor(x_range, y_range):
    position, target = overview_eye(x_range, y_range)
    look = np.subtract(target, position)
    for x in x_range:
        for y in y_range:
            to = np.subtract([x, y, 0], position)
            angle = math.degrees(math.acos(to @ look / np.linalg.norm(to) / np.linalg.norm(look)))
            assert angle < FIT_FOV / 2
    assert target == [sum(x_range) / 2, sum(y_range) / 2, 0.0] and position[0] == target[0]
    assert position[1] < target[1] and position[2] > 0  # from the south, above


def test_corners_keep_the_turns_and_the_far_end_of_a_drive_that_comes_back():
    line = np.linspace(0, 1, 11)
    square = np.r_[
        np.c_[line, 0 * line],  # east
        np.c_[np.ones(5), np.zeros(5)],  # turning on the spot
        np.c_[np.ones(11), line],  # north
        np.c_[1 - line, np.ones(11)],  # west
    ]
    assert corners(square).tolist() == [0, 10, 26, 37]
    out_and_back = np.r_[np.c_[line, 0 * line], np.c_[line[::-1], 0 * line]]
    assert corners(out_and_back).tolist() == [0, 10, 21]
    rng = np.random.default_rng(0)  # any path: every point within the tolerance of the kept line
    walk = np.cumsum(rng.normal(0, 0.01, (500, 2)), axis=0)
    kept = corners(walk, tol=0.005)
    for a, b in zip(kept[:-1], kept[1:]):
        for p in walk[a : b + 1]:
            ab, ap = walk[b] - walk[a], p - walk[a]
            u = np.clip(ap @ ab / (ab @ ab), 0, 1) if ab @ ab else 0.0
            assert np.linalg.norm(ap - u * ab) <= 0.005 + 1e-12


def test_the_path_reaches_the_robot_at_every_tick_and_never_runs_ahead(replay):
    rrd, recs = replay
    poses = _path(recs, 0)["poses"]
    kept = corners(poses[:, 1:3])
    path, leg = _chunks(rrd, "/world/path"), _chunks(rrd, "/world/path/leg")
    assert np.allclose(_seconds(path["sim_time"]), poses[kept, 0])  # a row at each corner
    assert np.allclose(
        path["LineStrips3D:strips"][-1][0], np.c_[poses[kept, 1:3], np.full(len(kept), 0.02)]
    )
    assert len(leg["sim_time"]) == len(poses)  # and the leg from the last corner, every tick
    ends = np.array([strip[0][-1][:2] for strip in leg["LineStrips3D:strips"]])
    assert np.allclose(ends, poses[:, 1:3])  # ends at the robot
    starts = np.array([strip[0][0][:2] for strip in leg["LineStrips3D:strips"]])
    last = kept[np.searchsorted(kept, np.arange(len(poses)), side="right") - 1]
    assert np.allclose(starts, poses[last, 1:3])  # where the path so far ends


def test_the_robot_is_a_labelled_body_with_a_heading(replay):
    rrd, _ = replay
    parts = _components(rrd)
    body, heading = parts["/world/robot/body"], parts["/world/robot/heading"]
    assert body["Boxes3D:labels"] == [["robot"]] and body["Boxes3D:show_labels"] == [[True]]
    assert np.allclose(body["Boxes3D:half_sizes"][0], [[0.089, 0.069, 0.096]])  # the Burger's box
    assert (
        heading["Arrows3D:vectors"][0][0][1:] == [0, 0]
        and heading["Arrows3D:vectors"][0][0][0] > 0.3
    )
    robot = palette.rgb(palette.ROBOT)
    assert body["Boxes3D:colors"] == heading["Arrows3D:colors"] == [[_packed(robot)]]


def _packed(rgb) -> int:
    """A colour as Rerun stores it: 0xRRGGBBAA."""
    r, g, b = rgb
    return (r << 24) | (g << 16) | (b << 8) | 0xFF


def test_a_stop_is_marked_before_the_obstacle_the_robot_stopped_for(replay):
    rrd, recs = replay
    path = _path(recs, 0)
    seen = recs.recognitions[recs.recognitions.episode == 0].reset_index(drop=True)
    texts = [t[0] for t in _chunks(rrd, "/recognition/result")["TextDocument:text"]]
    stopped = [k for k, t in enumerate(texts) if "stopped before it" in t]
    assert 0 < len(stopped) < len(seen)  # the tiny cell both stops and drives on
    stops = _chunks(rrd, "/world/stops")  # a Clear at the episode's start, then every stop
    ticks = path["pictures"][stopped]
    x, y, yaw = path["poses"][ticks, 1], path["poses"][ticks, 2], path["poses"][ticks, 3]
    ahead = STOP_AHEAD * 1.0  # of the 1 m cell
    expected = np.c_[
        x + ahead * np.cos(yaw), y + ahead * np.sin(yaw), np.full(len(ticks), MARK_HEIGHT)
    ]
    assert np.allclose(stops["Points3D:positions"][-1], expected)
    assert np.allclose(_seconds(stops["sim_time"])[1:], path["poses"][ticks, 0])
    assert stops["Points3D:colors"][-1] == [_packed(palette.rgb(palette.RESELECTED))]
    assert stops["Points3D:radii"][-1] == [np.float32(STOP_RADIUS)]
    assert [lab.split(",")[0] for lab in stops["Points3D:labels"][-1]] == [
        f"stop: step {int(s)}" for s in seen.step[stopped]
    ]


def test_collisions_count_up_in_steps_at_each_contact(replay):
    rrd, recs = replay
    path = _path(recs, 0)
    series = _chunks(rrd, "/metrics/collisions")
    k = len(path["contacts"])
    counts = [0.0] + [float(c) for i in range(k) for c in (i, i + 1)]  # before, after each contact
    assert [v[0] for v in series["Scalars:scalars"]] == counts
    assert np.allclose(
        _seconds(series["sim_time"])[1:],
        np.repeat(path["poses"][path["contacts"][:, 0].astype(int), 0], 2),
    )


def test_the_legend_shows_every_colour_of_the_palette_with_its_name(replay):
    rrd, recs = replay
    parts = _components(rrd)
    names = recs.meta.maze["categories"]
    legend = parts["/world/legend"]
    assert legend["Points3D:labels"][0] == names + ["start", "goal", "robot", "collision", "stop"]
    hexes = [palette.category(c) for c in range(len(names))] + list(MARKS.values())
    assert legend["Points3D:colors"][0] == [_packed(palette.rgb(h)) for h in hexes]
    text = parts["/legend"]["TextDocument:text"][0][0]
    for c, name in enumerate(names):
        assert f"{name} ({palette.category(c)})" in text
    for name, h in MARKS.items():
        assert f"**{name}** ({h})" in text
    cells = parts["/world/cells"]  # the start and goal tiles, labelled
    assert cells["Boxes3D:labels"][0] == ["start", "goal"]
    assert cells["Boxes3D:colors"][0] == [
        _packed(palette.rgb(palette.START)),
        _packed(palette.rgb(palette.GOAL)),
    ]
    layout = recs.meta.maze["layout"]
    assert np.allclose(
        [c[:2] for c in cells["Boxes3D:centers"][0]], [[-2, 2], [2, -2]]
    )  # S top left, G bottom right
    assert layout[0][0] == "S" and layout[-1][-1] == "G"


def test_events_are_on_the_step_timeline_with_their_levels(replay):
    rrd, recs = replay
    log = _chunks(rrd, "/events")
    steps = recs.steps[recs.steps.episode == 0].reset_index(drop=True)
    levels = {"ERROR": S.FLAG_COLLIDED, "WARN": S.FLAG_RESELECTED}
    flagged = 0
    for text, level, step in zip(log["TextLog:text"], log["TextLog:level"], log["step"]):
        t = int(text[0].split("step ")[1].split(":")[0])
        assert step == t  # episode 0: the steps count from 0
        if re.search(r"step \d+: cell \d+ action \w+: ", text[0]):  # what the step's flags say
            flagged += 1
            flags = int(steps["flags"][t])
            worst = next((name for name, bit in levels.items() if flags & bit), "INFO")
            assert level == [worst], text
    assert flagged == int((steps["flags"] != 0).sum())  # every flagged step
    pictures = [t[0] for t in log["TextLog:text"] if ": picture " in t[0] and "predicted" in t[0]]
    assert len(pictures) == int((recs.recognitions.episode == 0).sum())  # every recognition
