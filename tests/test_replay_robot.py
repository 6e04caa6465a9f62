"""The robot cell's replay in 3D (pipeline.robot.replay) through the one reader: a tiny real robot
cell replayed by the stage, what it shares with the grid's replay, and every odd robot record
refused in one error line naming the file and the field."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from entry import cli
from synthetic_records import make_batch

from pipeline.records import RecordWriter, read_records
from pipeline.records import schema as S
from pipeline.replay import ReplayError, build_replay
from pipeline.replay.robot3d import HIT_RADIUS, MARK_HEIGHT
from pipeline.stages.replay import WORLDS

TRIALS = [
    "world=robot3d",
    "method=fewshot_dss",
    "recogniser=fixed_accuracy",
    "runs=1",
    "episodes=3",
    "progress=false",
    "overwrite=true",
]


@pytest.fixture(scope="session")
def cell(tmp_path_factory) -> Path:
    """A tiny robot cell's records (the trials stage, in this process): 1 run of 3 episodes (also
    for tests/test_replay_robot_scene.py)."""
    from pipeline.stages import run_stage

    folder = tmp_path_factory.mktemp("robot") / "tiny" / "fewshot_dss_robot3d"
    run_stage("trials", [*TRIALS, f"out={folder}"])
    return folder / "records.mcap"


def _chunks(rrd: Path, entity: str) -> dict[str, list]:
    """The columns of ``entity``'s temporal rows, in ``sim_time`` order (an .rrd's chunks need not
    keep the order rows were logged in)."""
    import rerun.chunk

    batches = [
        ch.to_record_batch().to_pydict()
        for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks()
        if str(ch.entity_path) == entity and not ch.is_static
    ]
    keys = {k for b in batches for k in b}  # a column a chunk lacks: None in its rows
    out = {k: [v for b in batches for v in b.get(k, [None] * len(b["sim_time"]))] for k in keys}
    order = np.argsort(_seconds(out.get("sim_time", [])), kind="stable")
    return {k: [v[i] for i in order] for k, v in out.items()}


def _entities(rrd: Path) -> set[str]:
    import rerun.chunk

    return {str(ch.entity_path) for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks()}


def _seconds(values) -> np.ndarray:
    """``sim_time`` column values (pandas Timedeltas or nanoseconds) as seconds."""
    return np.array([v.total_seconds() if hasattr(v, "total_seconds") else v / 1e9 for v in values])


def _path(recs, episode: int) -> dict:
    """The episode's path as the replay expands it (pipeline.robot.motion.episode_path)."""
    from pipeline.robot.motion import episode_path
    from pipeline.world.layout import parse_layout

    meta = recs.meta
    steps = recs.steps[recs.steps.episode == episode]
    seen = recs.recognitions[recs.recognitions.episode == episode]
    return episode_path(
        meta.info["robot"],
        parse_layout("\n".join(meta.maze["layout"])),
        meta.obstacles[0],
        list(zip(steps.state, steps.action, steps["flags"])),
        [{"step": int(r.step), "action": int(r.action)} for r in seen.itertuples()],
    )


def test_the_stage_replays_a_robot_cell_in_3d_from_its_records(cell, tmp_path, capsys):
    """The robot's body at every pose of its path on ``sim_time``, the path, the scene, the live
    picture of each recognition (the file's own bytes) and the views the grid's replay has."""
    from pipeline.stages import run_stage

    recs = read_records(cell)
    assert recs.meta.config["world"] == "robot3d" and not (cell.parent / "robot.mcap").exists()
    rrd = run_stage("replay", [f"file={cell}", "run=0", "viewer=none", f"out={tmp_path / 'r.rrd'}"])
    first = int(recs.recognitions.episode.min())
    assert f"episode={first}: the first of run 0 with a recognition" in capsys.readouterr().out
    assert rrd == tmp_path / "r.rrd" and rrd.stat().st_size > 0
    entities = _entities(rrd)
    assert {
        "/world/path",
        "/world/robot",
        "/world/obstacles",
        "/world/unsafe",
        "/events",
    } <= entities
    assert any(e.startswith("/world/scene/obstacle") for e in entities)
    assert any(e.startswith("/world/scene/wall") for e in entities)
    assert {"/recognition/result", "/support/categories", "/support/substituted"} <= entities
    path = _path(recs, first)
    body = _chunks(rrd, "/world/robot")
    assert len(body["sim_time"]) == len(path["poses"])
    assert np.allclose(_seconds(body["sim_time"]), path["poses"][:, 0])
    seen = recs.recognitions[recs.recognitions.episode == first]
    pictures = _chunks(rrd, "/world/robot/camera/image")
    assert [bytes(b[0]) for b in pictures["EncodedImage:blob"]] == [
        recs.meta.pictures[int(p)] for p in seen.picture
    ]  # the camera's live pictures, each when it was taken
    assert np.allclose(_seconds(pictures["sim_time"]), path["poses"][path["pictures"], 0])
    texts = [t[0] for t in _chunks(rrd, "/recognition/result")["TextDocument:text"]]
    assert len(texts) == len(seen)
    assert all("stopped before it" in t or "drove on: collision" in t for t in texts)


def test_a_collision_is_logged_where_and_when_the_robot_touched(cell, tmp_path):
    recs = read_records(cell)
    steps = recs.steps
    episode = int(steps.episode[(steps["flags"] & S.FLAG_COLLIDED) != 0].iloc[0])
    rrd = build_replay(cell, 0, episode, out=tmp_path / "c.rrd", worlds=WORLDS)
    path = _path(recs, episode)
    contacts = path["contacts"]
    points = _chunks(rrd, "/world/collisions")  # a Clear at the episode's start, then every contact
    assert np.allclose(
        points["Points3D:positions"][-1],
        np.c_[contacts[:, 1:], np.full(len(contacts), MARK_HEIGHT)],
    )
    assert points["Points3D:radii"][-1] == [np.float32(HIT_RADIUS)]  # a big ball
    at = path["poses"][contacts[:, 0].astype(int), 0]
    assert np.allclose(_seconds(points["sim_time"])[1:], at)
    log = _chunks(rrd, "/events")
    collided = [
        s for s, t in zip(_seconds(log["sim_time"]), log["TextLog:text"]) if "collided" in t[0]
    ]
    assert np.allclose(collided, at)  # the events line at the contact, not the step's start
    hits = [t[0] for t in log["TextLog:text"] if "collided" in t[0]]
    width, placed = len(recs.meta.maze["layout"][0]), {o["cell"]: o for o in recs.meta.obstacles[0]}
    rows = steps[(steps.episode == episode) & ((steps["flags"] & S.FLAG_COLLIDED) != 0)]
    for (x, y), line, r in zip(contacts[:, 1:], hits, rows.itertuples()):  # what it hit, and where
        o = placed[int(r.state) + (-width, 1, width, -1)[int(r.action)]]  # the cell it drove into
        name = f"{recs.meta.maze['categories'][o['category']]} #{o['instance']} r{o['orientation']}"
        assert f": collided into the {name} at (x, y) = ({x:.2f}, {y:.2f}) m" in line, line


def test_a_whole_run_plays_its_episodes_back_to_back(cell, tmp_path):
    recs = read_records(cell)
    rrd = build_replay(cell, 0, whole_run=True, out=tmp_path / "w.rrd", worlds=WORLDS)
    lengths = [len(_path(recs, e)["poses"]) for e in sorted(set(recs.episodes.episode))]
    times = _seconds(_chunks(rrd, "/world/robot")["sim_time"])
    assert len(times) == sum(lengths) and (np.diff(times) > 0).all()  # none at the same moment
    strips = _chunks(rrd, "/world/path")["LineStrips3D:strips"]
    starts = [k for k, s in enumerate(strips) if len(s[0]) == 1]  # each episode's path begins anew
    assert len(starts) == len(lengths) and starts[0] == 0
    steps = _chunks(rrd, "/world/robot")["step"]  # the steps count on across the episodes
    assert steps[-1] == len(recs.steps) - 1 and (np.diff(steps) >= 0).all()


def test_a_missing_episode_is_named_and_the_robot_needs_its_reader(cell, tmp_path):
    with pytest.raises(ReplayError, match="run 0 has no recorded episode 9"):
        build_replay(cell, 0, 9, out=tmp_path / "x.rrd", worlds=WORLDS)
    with pytest.raises(ReplayError, match="robot cell .*pass worlds=") as e:
        build_replay(cell, 0, 0, out=tmp_path / "x.rrd")  # the reader is the stage's to give
    assert e.value.key == "file" and not (tmp_path / "x.rrd").exists()


def test_a_robot_cell_without_recognitions_says_why_as_the_grid_does(tmp_path):
    """A shield recognises no pictures: the robot moves, the recognition views say why (static)."""
    from pipeline.stages import run_stage

    out = tmp_path / "shield"
    shield = ["world=robot3d", "method=shield", "runs=1", "episodes=1", "progress=false"]
    run_stage("trials", [*shield, f"out={out}"])
    rrd = build_replay(out / "records.mcap", 0, 0, out=tmp_path / "s.rrd", worlds=WORLDS)
    entities = _entities(rrd)
    assert {"/world/robot", "/world/path", "/world/robot/camera/image/note"} <= entities
    assert "/world/robot/camera/image" not in entities
    assert not _chunks(rrd, "/recognition/result")  # the note only, static


# ---------------------------------------------------------------- odd robot records
def rewrite(recs, out: Path, *, config=None, info=None, robot=None, recognitions=None) -> Path:
    """Record ``recs`` (one file's records) again at ``out`` through the one writer, with its
    config, ``info``, motion table (``robot``) or recognitions frame replaced."""
    meta = recs.meta
    keep = ("layout", "name", "categories", "actions", "moves")
    frame = recs.recognitions if recognitions is None else recognitions
    scores = [c for c in frame.columns if c.startswith("score_")]
    support: dict[int, list[bytes]] = {}
    for (c, _), png in sorted(meta.support_pictures.items()):
        support.setdefault(c, []).append(png)
    metadata = {
        "config": meta.config if config is None else config,
        "seeds": meta.seeds,
        "info": meta.info["info"] if info is None else info,
        "robot": meta.info["robot"] if robot is None else robot,
    }
    with RecordWriter(
        out,
        metadata={k: v for k, v in metadata.items() if v is not ...},
        maze={k: meta.maze[k] for k in keep},
        runs=meta.obstacles,
        pictures=meta.pictures,
        support_pictures=support,
    ) as w:
        for e in sorted(set(recs.episodes.episode)):
            for s in recs.substitutions[recs.substitutions.episode == e].itertuples():
                where = {"run": 0, "episode": e, "step": s.step, "picture": s.picture}
                w.substitution(**where, category=s.category, position=s.position)
            steps, seen = recs.steps[recs.steps.episode == e], frame[frame.episode == e]
            added = recs.unsafe[recs.unsafe.episode == e]
            summary = recs.episodes[recs.episodes.episode == e].iloc[0]
            sums = (
                "collisions",
                "return_",
                "reached_goal",
                "prevented",
                "epsilon",
                "greedy_optimal",
            )
            w.episodes(
                **make_batch(
                    [
                        {
                            "run": 0,
                            "episode": e,
                            "states": steps.state.to_numpy(),
                            "actions": steps.action.to_numpy(),
                            "rewards": steps.reward.to_numpy(),
                            "flags": steps["flags"].to_numpy(),
                            "recognitions": {
                                **{
                                    k: seen[k].to_numpy()
                                    for k in (
                                        "step",
                                        "state",
                                        "action",
                                        "picture",
                                        "predicted",
                                        "true",
                                    )
                                },
                                "scores": seen[scores].to_numpy(np.float32)
                                if scores
                                else np.zeros((len(seen), 0), np.float32),
                            },
                            "unsafe_added": {
                                k: added[k].to_numpy()
                                for k in ("step", "state", "action", "source")
                            },
                            "summary": {k: summary[k] for k in sums},
                        }
                    ]
                )
            )
    return out


def _config(recs, **robot):
    config = copy.deepcopy(recs.meta.config)
    config["robot"] = {k: v for k, v in {**config["robot"], **robot}.items() if v is not ...}
    return config


def _table(recs, edit):
    table = copy.deepcopy(recs.meta.info["robot"])
    edit(table)
    return table


def _recognitions(recs, **columns):
    frame = recs.recognitions.copy()
    for name, value in columns.items():
        if value is ...:
            frame = frame.drop(columns=[c for c in frame.columns if c.startswith(name)])
        else:
            frame.loc[frame.index[0], name] = value
    return frame


ODD = {  # name -> (how to rewrite the records, what the one error line says)
    "no motion table": (
        lambda r: {"robot": ...},
        "info.robot: no motion table, so the robot's path cannot be drawn",
    ),
    "robot.cell missing": (
        lambda r: {"config": _config(r, cell=...)},
        "config robot.cell: missing: the robot's cell size (m) builds its world",
    ),
    "robot.cell a word": (
        lambda r: {"config": _config(r, cell="big")},
        "config robot.cell: 'big' is not a number",
    ),
    "robot.cell out of range": (
        lambda r: {"config": _config(r, cell=1e6)},
        "config robot.cell: cell=1000000.0: the robot world's cell must lie in 0.5-2.0 m",
    ),
    "a drive without poses": (
        lambda r: {"robot": _table(r, lambda t: t["drives"]["free"].update(poses=[]))},
        "info.robot.drives.free.poses: no poses",
    ),
    "a NaN pose": (
        lambda r: {"robot": _table(r, lambda t: t["turns"][1][0].__setitem__(0, float("nan")))},
        "info.robot.turns[1]: NaN or infinite pose at row 0",
    ),
    "true category 99": (
        lambda r: {"recognitions": _recognitions(r, true=99)},
        "recognitions.true: category 99 at run 0 episode 0 step ",
    ),
    "recognitions without scores": (
        lambda r: {"recognitions": _recognitions(r, score_=...)},
        "recognitions.scores: the recognition at run 0 episode 0 step ",
    ),
}


@pytest.mark.parametrize("odd", list(ODD))
def test_an_odd_robot_record_is_one_error_line_naming_the_file_and_field(cell, tmp_path, odd):
    how, says = ODD[odd]
    recs = read_records(cell)
    path = rewrite(recs, tmp_path / "cell" / "records.mcap", **how(recs))
    out = tmp_path / "odd.rrd"
    res = cli("replay", f"file={path}", "run=0", "episode=0", "viewer=none", f"out={out}")
    assert res.returncode == 2, res.stderr
    assert res.stderr.splitlines() == [res.stderr.strip()]  # one line, no traceback
    assert res.stderr.startswith(f"error: config key 'file': {path}: {says}"), res.stderr
    assert not out.exists()


def test_the_rewritten_record_replays_as_the_original(cell, tmp_path):
    """The rewriting above changes only what it is told to (so each odd case is that field alone)."""
    recs = read_records(cell)
    path = rewrite(recs, tmp_path / "same" / "records.mcap")
    again = read_records(path)
    assert again.meta.info == recs.meta.info and again.meta.config == recs.meta.config
    assert again.recognitions.drop(columns="file").equals(recs.recognitions.drop(columns="file"))
    assert build_replay(path, 0, 0, out=tmp_path / "same.rrd", worlds=WORLDS).exists()
    assert json.dumps(again.meta.obstacles) == json.dumps(recs.meta.obstacles)
