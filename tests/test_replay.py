"""Replay of recorded episodes in Rerun (pipeline.records.replay, stage ``replay``)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.records.replay import ReplayError, build_replay
from synthetic_records import write_synthetic

ROOT = Path(__file__).resolve().parents[1]


def _rows(rrd: Path) -> dict[str, int]:
    """Entity path -> number of temporal rows (static entities map to 0)."""
    import rerun.chunk

    rows: dict[str, int] = {}
    for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks():
        path = str(ch.entity_path)
        rows[path] = rows.get(path, 0) + (0 if ch.is_static else ch.num_rows)
    return rows


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    written = write_synthetic(d / "r.mcap", runs=2, episodes_per_run=5, seed=3)
    return d / "r.mcap", written


def test_replay_of_one_episode_has_the_entities_and_one_row_per_step(recorded, tmp_path):
    path, written = recorded
    f = next(w for w in written if w["run"] == 1 and w["episode"] == 3)
    rows = _rows(build_replay(path, 1, 3, out=tmp_path / "e.rrd"))
    n = len(f["states"])
    for entity in ("/maze/robot", "/maze/robot/action", "/maze/robot/trajectory", "/metrics/return"):
        assert rows[entity] == n, entity
    assert {"/maze/cells", "/maze/obstacles"} <= rows.keys()
    n_rec = len(f["recognitions"]["step"])
    assert rows.get("/recognition/picture", 0) == rows.get("/recognition/scores", 0) == n_rec > 0
    assert rows["/maze/unsafe"] == 1 + len(set(f["unsafe_added"]["step"].tolist()))
    if f["_substitutions"]:
        assert any(k.startswith("/support/") for k in rows)
    assert rows["/events"] >= int((f["flags"] != 0).sum())


def test_replay_of_a_whole_run_covers_every_step(recorded, tmp_path):
    path, written = recorded
    rows = _rows(build_replay(path, 0, whole_run=True, out=tmp_path / "run.rrd"))
    assert rows["/maze/robot"] == sum(len(w["states"]) for w in written if w["run"] == 0)


def test_replay_names_a_missing_episode(recorded, tmp_path):
    path, _ = recorded
    with pytest.raises(ReplayError, match="run 1 has no recorded episode 7 \\(episodes 0..4"):
        build_replay(path, 1, 7, out=tmp_path / "x.rrd")
    with pytest.raises(ReplayError, match="no recorded episode of run 5"):
        build_replay(path, 5, 0, out=tmp_path / "x.rrd")


def test_replay_shows_recorded_q_values(tmp_path):
    from pipeline.records import RecordWriter

    n = 4
    with RecordWriter(tmp_path / "q.mcap", maze={"layout": ["S.", ".G"]}) as w:
        for e in range(2):
            w.episode(run=0, episode=e, states=np.array([0, 1, 3, 2])[:n], actions=np.array([1, 2, 3, 0]),
                      rewards=np.zeros(n), flags=np.zeros(n, np.uint8), recognitions={}, unsafe_added={},
                      summary={"steps": n, "collisions": 0, "return_": 0.0, "reached_goal": False,
                               "prevented": 0, "epsilon": 0.1, "greedy_optimal": False}, q_values=np.full((4, 4), e + 0.5))
    rows = _rows(build_replay(tmp_path / "q.mcap", 0, 1, out=tmp_path / "q.rrd"))
    assert rows["/q_values/max"] == 2 and "/derived/visits" not in rows


def test_replay_stage_with_a_positional_file(recorded, tmp_path):
    path, written = recorded
    out = tmp_path / "stage.rrd"
    res = subprocess.run([sys.executable, "-m", "pipeline", "replay", str(path), "run=0", "episode=2",
                          f"out={out}"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    f = next(w for w in written if w["run"] == 0 and w["episode"] == 2)
    assert _rows(out)["/maze/robot"] == len(f["states"])
    bad = subprocess.run([sys.executable, "-m", "pipeline", "replay", f"file={path}", "run=0", "episode=2",
                          "viewer=desktop"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "config key 'viewer'" in bad.stderr


def _columns(rrd: Path, entity: str) -> dict[str, list]:
    import rerun.chunk

    out: dict[str, list] = {}
    for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks():
        if str(ch.entity_path) == entity:
            for k, v in ch.to_record_batch().to_pydict().items():
                out.setdefault(k, []).extend(v)
    return out


def test_the_trials_stage_records_the_worlds_moves_and_names(tmp_path):
    from pipeline.records import read_records
    from pipeline.stages._common import run_stage
    from pipeline.world.maze import ACTION_NAMES, MOVES
    from pipeline.world.pictures import CATEGORIES

    run_stage("trials", ["method=shield", "maze=5x5", "runs=1", "episodes=2", "record=true", f"out={tmp_path}",
                         "progress=false"])
    (path,) = tmp_path.rglob("records.mcap")
    maze = read_records(path, pictures=False).meta.maze
    assert (maze["actions"], maze["moves"], maze["categories"]) == (list(ACTION_NAMES), list(MOVES), list(CATEGORIES))


def test_replay_draws_with_the_files_moves_and_names(tmp_path):
    from pipeline.records import RecordWriter

    def write(path, **maze):
        with RecordWriter(path, maze={"layout": ["S.", ".G"], **maze}) as w:
            w.episode(run=0, episode=0, states=np.array([0, 1, 3, 2]), actions=np.array([1, 2, 3, 0]),
                      rewards=np.zeros(4), flags=np.array([1, 0, 0, 8], np.uint8), recognitions={}, unsafe_added={},
                      summary={"steps": 4, "collisions": 0, "return_": 0.0, "reached_goal": True, "prevented": 1,
                               "epsilon": 0.1, "greedy_optimal": False})
        return build_replay(path, 0, 0, out=path.with_suffix(".rrd"))

    own = write(tmp_path / "own.mcap", actions=["up", "right", "down", "left"], moves=[(-1, 0), (0, 2), (1, 0), (0, -2)])
    vectors = [v[0] for v in _columns(own, "/maze/robot/action")["Arrows2D:vectors"]]
    assert np.allclose(vectors, [[0.8, 0], [0, 0.4], [-0.8, 0], [0, -0.4]])  # (x, y) = (d_col, d_row) * 0.4
    assert [t[0] for t in _columns(own, "/events")["TextLog:text"]] == [
        "run 0 ep 0 step 0: cell 0 action right: reselected", "run 0 ep 0 step 3: cell 2 action up: goal"]
    old = write(tmp_path / "old.mcap")  # a file without moves or names (as older files): N, E, S, W
    vectors = [v[0] for v in _columns(old, "/maze/robot/action")["Arrows2D:vectors"]]
    assert np.allclose(vectors, [[0.4, 0], [0, 0.4], [-0.4, 0], [0, -0.4]])
    assert "action E: reselected" in _columns(old, "/events")["TextLog:text"][0][0]
    with pytest.raises(ValueError, match="maze.moves"):
        write(tmp_path / "bad.mcap", actions=["up", "down"], moves=[(-1, 0), (0, 1), (1, 0)])
