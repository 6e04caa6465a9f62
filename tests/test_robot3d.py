"""The robot in MuJoCo (issue 30): the Burger's limits, range sensing, collisions as contacts,
self-recovery, live camera pictures and few-shot reasoning with the oracle."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.rl.agents import TabularAgent, run_episode
from pipeline.rl.oracle import OracleRecogniser
from pipeline.rl.runner import make_run_world
from pipeline.robot.env import PICTURE_SIZE, SafeNavigation3DEnv
from pipeline.robot.live import LiveView
from pipeline.robot.model import MAX_SPEED, MAX_TURN
from pipeline.robot.sim import HEADINGS, RobotSim, wheel_limited
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import load_layout
from pipeline.world.pictures import N_CATEGORIES

#: Self-recovery's stated tolerance (docs/robot3d.md): back within 2 cm of the previous centre.
RECOVERY_TOLERANCE = 0.02


@pytest.fixture(scope="module")
def maze():
    layout = load_layout("5x5")
    geometry = build_geometry(layout)
    world = make_run_world(geometry, seed=11, run=0)
    return layout, geometry, RobotSim(layout, world.placement)


def test_wheel_limits_keep_the_burgers_speeds():
    for v, w in [(5.0, 0.0), (0.0, 50.0), (-3.0, -9.0), (0.1, 1.0)]:
        v2, w2 = wheel_limited(v, w)
        assert abs(v2) <= MAX_SPEED + 1e-12 and abs(w2) <= MAX_TURN + 1e-12
    assert wheel_limited(0.1, 0.5) == pytest.approx((0.1, 0.5))


def test_range_sensor_finds_exactly_the_occupied_neighbours(maze):
    layout, geometry, sim = maze
    for s in range(layout.n_cells):
        if s in layout.obstacles:
            continue
        sim.reset(s, heading=s % 4)
        scan = sim.scan()
        for a in range(4):
            if sim.inside(s, a):
                assert sim.occupied(a, scan) == (geometry.obstacle[s, a] >= 0), (s, a)


def test_driving_into_an_obstacle_is_one_contact_and_recovery_returns(maze):
    layout, geometry, sim = maze
    s, a = (int(x) for x in np.argwhere(geometry.obstacle >= 0)[0])
    sim.reset(s)
    result = sim.move(s, a)
    assert result.collided and result.cell == s
    o = geometry.obstacle[s, a]
    assert result.contact_geom == f"obstacle{o}_box"
    # the contact lies between the two cells' centres, on the obstacle's side
    start, blocked = sim.map.centre(s), sim.map.centre(layout.obstacles[o])
    along = np.dot(np.array(result.contact[:2]) - start, blocked - start) / sim.map.cell**2
    assert 0.2 < along < 1.0
    x, y, yaw = sim.pose()
    assert np.hypot(x - start[0], y - start[1]) < RECOVERY_TOLERANCE
    # poses at 10 Hz, speeds inside the Burger's limits
    t, xs, ys, yaws = np.array(result.poses).T
    assert np.allclose(np.diff(t), 0.1)
    assert np.all(np.hypot(np.diff(xs), np.diff(ys)) / 0.1 <= MAX_SPEED + 1e-3)


def test_free_move_arrives_and_off_grid_move_stays(maze):
    layout, geometry, sim = maze
    s = layout.start
    a = next(a for a in range(4) if geometry.next_cell[s, a] != s)
    sim.reset(s)
    result = sim.move(s, a)
    assert not result.collided and result.cell == geometry.next_cell[s, a]
    x, y, yaw = sim.pose()
    assert np.hypot(*(np.array([x, y]) - sim.map.centre(result.cell))) < 0.01
    assert abs((yaw - HEADINGS[a] + np.pi) % (2 * np.pi) - np.pi) < 0.01
    assert 1.0 / MAX_SPEED < result.sim_time < 1.0 / MAX_SPEED + 3.0
    off = next(a for a in range(4) if not sim.inside(result.cell, a))
    stay = sim.move(result.cell, off)
    assert stay.cell == result.cell and stay.sim_time == 0.0 and not stay.collided


def test_timestep_must_divide_the_control_period():
    with pytest.raises(ValueError, match="timestep"):
        RobotSim(
            load_layout("5x5"),
            make_run_world(build_geometry(load_layout("5x5")), 0, 0).placement,
            timestep=0.03,
        )


def _episodes(env, n: int, seed: int):
    agent = TabularAgent(env.method, env.layout.n_cells, 1234)
    infos, results = [], []
    step = env.step

    def logged(a):
        out = step(a)
        infos.append(out[4])
        return out

    env.step = logged
    for ep in range(n):
        results.append(run_episode(env, agent, seed=seed if ep == 0 else None))
    env.step = step
    return results, infos


def test_oracle_fewshot_reaches_the_goal_with_no_contact():
    env = SafeNavigation3DEnv("5x5", "fewshot_dss", OracleRecogniser())
    results, infos = _episodes(env, 8, seed=5)
    assert not any(i["collided"] for i in infos)
    assert sum(i["cost"] for i in infos) == 0.0
    assert any(i["prevented"] for i in infos)  # it met obstacles and recognised them
    assert all(r["rewards"][-1] == 1.0 for r in results)  # every episode reached the goal
    env.close()


@pytest.mark.slow
def test_shield_collides_through_contacts_and_recovers():
    env = SafeNavigation3DEnv("5x5", "shield")
    results, infos = _episodes(env, 3, seed=5)
    hits = [i for i in infos if i["collided"]]
    assert hits and all(i["cost"] == 1.0 and i["contact"] is not None for i in hits)
    assert all(i["camera"] is None for i in infos)  # shield sees no pictures
    env.close()


def test_same_seed_same_trajectory():
    runs = []
    for _ in range(2):
        env = SafeNavigation3DEnv("5x5", "fewshot", OracleRecogniser())
        results, infos = _episodes(env, 2, seed=9)
        runs.append((results, [(i["poses"], i["contact"], i["sim_time"]) for i in infos]))
        env.close()
    (r1, i1), (r2, i2) = runs
    assert i1 == i2
    for a, b in zip(r1, r2):
        assert all(np.array_equal(a[k], b[k]) for k in a)


def test_live_picture_of_each_category_is_classified_by_the_oracle():
    """The oracle names the category of the obstacle on the cell the live picture looks at: it
    reads the world's ground truth there (``SafeNavigation3DEnv._truth_at``); the picture itself
    must show an obstacle (not the empty floor), and pictures of different obstacles differ."""
    env = SafeNavigation3DEnv("5x5", "fewshot", OracleRecogniser())
    env.reset(seed=2)
    g, cats = env.geometry, env.world.true_category
    seen, pictures = set(), []
    for s, a in np.argwhere(g.obstacle >= 0):
        o = g.obstacle[s, a]
        if cats[o] in seen:
            continue
        env.unsafe[:] = False
        env._place(int(s))
        _, _, _, _, info = env.step(int(a))
        assert info["prevented"] and info["camera"].shape == (PICTURE_SIZE, PICTURE_SIZE, 3)
        assert int(np.argmax(info["scores"])) == cats[o]
        assert info["camera"].std() > 10  # something in view
        seen.add(int(cats[o]))
        pictures.append(info["camera"].astype(int))
    assert seen == set(range(N_CATEGORIES))
    for i in range(len(pictures)):
        for j in range(i):
            assert np.abs(pictures[i] - pictures[j]).mean() > 5
    env.close()


@pytest.fixture(scope="module", params=["relation_net", "protonet"])
def live_network(request, tmp_path_factory):
    """An untrained few-shot network on a synthetic picture set: what a fresh clone has (no
    rendered pictures); the test checks the plumbing, not the accuracy."""
    from fakes import untrained_network

    from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser
    from pipeline.robot.live import live

    cls = {"relation_net": RelationRecogniser, "protonet": ProtoRecogniser}[request.param]
    root = tmp_path_factory.mktemp(request.param)
    ckpt, _ = untrained_network(root, request.param)
    return live(cls.from_files(ckpt, root / "images", substitution_way=1))


def test_few_shot_networks_score_live_pictures_and_substitute_them(live_network):
    env = SafeNavigation3DEnv("5x5", "fewshot_dss", live_network)
    env.reset(seed=4)
    s, a = (int(x) for x in np.argwhere(env.geometry.obstacle >= 0)[0])
    env._place(s)
    env.sim.face(a)
    picture = env.sim.picture(PICTURE_SIZE)
    scores = live_network.live_scores(env.run_id, LiveView(picture, -1, -1))
    assert scores.shape == (N_CATEGORIES,) and np.all((scores >= 0) & (scores <= 1))
    # a network reads the picture only, never the world's truth or the query picture's id
    assert np.array_equal(scores, live_network.live_scores(env.run_id, LiveView(picture, 3, 17)))
    category = int(np.argmin(scores))
    position = live_network.learn_from_live(env.run_id, LiveView(picture, category, -1))
    assert 0 <= position < 5
    members = live_network.inner.support_members(env.run_id)
    assert members[category, position] >= live_network.LIVE_CODE_BASE
    after = live_network.live_scores(env.run_id, LiveView(picture, -1, -1))
    assert after[category] != scores[category]  # the class state now holds the live picture
    if live_network.inner.kind == "relation_net":  # protonet's softmax couples the categories
        others = [c for c in range(N_CATEGORIES) if c != category]
        assert np.array_equal(after[others], scores[others])
    env.close()


def test_a_model_of_recognition_answers_a_live_picture_as_its_query_picture():
    """fixed_accuracy on the robot: the side of an obstacle is recognised exactly when the grid's
    model recognises its query picture, and a collision teaches that picture (``learn``)."""
    from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser
    from pipeline.robot.live import live

    model = FixedAccuracyRecogniser(p=0.5)
    rec = live(model)
    rec.start_run(0, seed=3)
    truth = OracleRecogniser().predictions(0)
    predicted = model.predictions(0)
    image = np.zeros((PICTURE_SIZE, PICTURE_SIZE, 3), np.uint8)
    for picture in range(len(truth)):
        scores = rec.live_scores(0, LiveView(image, int(truth[picture]), picture))
        if predicted[picture] == truth[picture]:
            assert scores[truth[picture]] == 1.0 and scores.sum() == 1.0
        else:
            assert not scores.any()  # not recognised: no score reaches any threshold
    wrong = int(np.flatnonzero(predicted != truth)[0])
    rec.learn_from_live(0, LiveView(image, int(truth[wrong]), wrong))
    assert rec.live_scores(0, LiveView(image, int(truth[wrong]), wrong)).max() == 1.0
    assert rec.describe() is None  # as on the grid, the model records no description


def test_gymnasium_ids_check_env_and_six_values():
    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pipeline
    from pipeline.envs import SixValueStep

    assert set(pipeline.ENV_IDS_3D) <= set(gymnasium.registry)
    env = gymnasium.make(
        "SafeNav3D-5x5-v0", method="fewshot", recogniser="oracle", render_mode="rgb_array"
    )
    check_env(env.unwrapped, skip_render_check=False)
    with pytest.raises(ValueError, match="7x7"):
        gymnasium.make("SafeNav3D-5x5-v0", maze="7x7")
    made = gymnasium.make("SafeNav3D-5x5-v0", method="fewshot", recogniser="fixed_accuracy",
                          recogniser_options={"p": 0.25})  # fmt: skip
    assert made.unwrapped.recogniser.inner.p == 0.25
    with pytest.raises(ValueError, match="nonesuch"):
        gymnasium.make("SafeNav3D-5x5-v0", method="fewshot", recogniser="nonesuch")
    with pytest.raises(ValueError, match="colour"):
        gymnasium.make("SafeNav3D-5x5-v0", method="fewshot", recogniser="oracle",
                       recogniser_options={"colour": 1})  # fmt: skip
    for env_id in ("SafeNav3D-5x5-v0", "SafeNav-5x5-v0"):
        wrapped = SixValueStep(gymnasium.make(env_id, method="shield"))
        wrapped.reset(seed=0)
        costs = []
        for a in (1, 1, 2, 2, 1, 1, 2, 2):
            obs, reward, cost, terminated, truncated, info = wrapped.step(a)
            costs.append(cost)
            assert cost == float(info["collided"])
            if terminated or truncated:
                break
        assert 1.0 in costs  # the start's east neighbour is an obstacle
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    env.close()


@pytest.mark.slow  # 10-20 s each
@pytest.mark.parametrize(
    "method,recogniser",
    [("shield", "oracle"), ("fewshot_dss", "oracle"), ("fewshot", "fixed_accuracy"),
     ("fewshot_dss", "fixed_accuracy")],
)  # fmt: skip
def test_robot_trials_match_the_grid_with_a_model_of_recognition(method, recogniser):
    """With the oracle or ``fixed_accuracy`` the robot's outcomes are the grid's: the same
    placement, exploration, recognitions and collisions from the same seed (a collision is a
    contact exactly where the grid has one; a model answers a live picture as its query picture)."""
    from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser

    def model():
        return OracleRecogniser() if recogniser == "oracle" else FixedAccuracyRecogniser(p=0.5)

    from pipeline.rl.methods import get_method
    from pipeline.rl.runner import run_trials
    from pipeline.robot.trials import run_robot_trials

    class Sink:
        def __init__(self):
            self.batches, self.robot, self.subs = [], [], []

        def episodes(self, **b):
            self.batches.append(b)

        def substitution(self, **k):
            self.subs.append(k)

        def episode(self, **k):
            self.robot.append(k)

    layout, spec, sink = load_layout("5x5"), get_method(method), Sink()
    robot = run_robot_trials(layout, spec, 2, 3, 0, recogniser=model(), sink=sink,
                             robot_sink=sink)  # fmt: skip
    grid = run_trials(layout, spec, 2, 3, 0, recogniser=model(), progress=False)
    for key in ("steps", "collisions", "returns", "reached_goal", "prevented", "greedy_optimal"):
        assert np.array_equal(getattr(robot, key), getattr(grid, key)), key
    assert len(sink.batches) == len(sink.robot) == 6
    for b, r in zip(sink.batches, sink.robot):
        assert r["sim_time"] > 0 and len(r["poses"]) >= 10 * r["sim_time"] - 1
        assert len(r["contacts"]) == int(b["summary"]["collisions"][0])
        assert len(r["pictures"]) == len(b["recognitions"]["episode"])


def test_trials_stage_runs_a_robot_cell_into_both_record_files(tmp_path):
    from pipeline.records import read_records
    from pipeline.robot.records import read_robot_records
    from pipeline.stages._common import run_stage

    args = ["method=fewshot", "world=robot3d", "recogniser=oracle", "runs=1", "episodes=3",
            "progress=false", "robot.threshold=0.9", "overwrite=true"]  # fmt: skip
    summary = run_stage("trials", [*args, f"out={tmp_path / 'a'}"])
    assert summary["collisions"]["mean"] == 0.0
    settings, episodes = read_robot_records(tmp_path / "a" / "robot.mcap")
    assert settings["threshold"] == 0.9 and len(episodes) == 3
    assert all(e["sim_time"] > 0 and e["poses"] for e in episodes)
    pictures = [p for e in episodes for p in e["pictures"]]
    assert pictures and all(np.argmax(p["scores"]) == p["true"] for p in pictures)
    records = read_records(tmp_path / "a" / "records.mcap")
    config = records.meta.config
    assert config["world"] == "robot3d" and config["robot"]["threshold"] == 0.9
    assert (records.recognitions["picture"] == -1).all()
    first = {n: (tmp_path / "a" / n).read_bytes() for n in ("records.mcap", "robot.mcap")}
    run_stage("trials", [*args, f"out={tmp_path / 'a'}"])  # the same seed again
    for name, data in first.items():
        assert (tmp_path / "a" / name).read_bytes() == data, name  # byte for byte


def test_fixed_accuracy_runs_on_the_robot_with_the_given_p(tmp_path):
    """Every recogniser runs with world=robot3d; its keys are applied (the recorded config is the
    one that ran) and p=0 recognises nothing, so no live picture stops the robot."""
    from pipeline.records import read_records
    from pipeline.robot.records import read_robot_records
    from pipeline.stages._common import run_stage

    run_stage("trials", ["method=fewshot", "world=robot3d", "recogniser=fixed_accuracy",
                         "recogniser.p=0.0", "runs=1", "episodes=2", "progress=false",
                         f"out={tmp_path}"])  # fmt: skip
    assert read_records(tmp_path / "records.mcap").meta.config["recogniser"]["p"] == 0.0
    _, episodes = read_robot_records(tmp_path / "robot.mcap")
    pictures = [p for e in episodes for p in e["pictures"]]
    assert pictures and not any(p["prevented"] for p in pictures)
    assert all(not np.any(p["scores"]) for p in pictures)


def _robot_records(path):
    from pipeline.robot.records import RobotRecordWriter

    writer = RobotRecordWriter(path, {"cell": 1.0, "threshold": 0.5})
    picture = {"step": 0, "time": 0.0, "state": 1, "action": 2, "scores": [0.1] * 5, "true": 3,
               "prevented": True, "substituted": -1,
               "image": np.full((8, 8, 3), 7, np.uint8)}  # fmt: skip
    for ep in range(3):
        writer.episode(run=0, episode=ep, sim_time=1.5, poses=[(0.0, 0.0, 0.0, 0.0)],
                       pictures=[dict(picture)], contacts=[])  # fmt: skip
    return writer.close()


@pytest.mark.parametrize("damage", ["cut", "garbage", "not_robot"])
def test_a_damaged_robot_record_file_is_named_in_one_error(tmp_path, damage):
    from pipeline.robot.records import RobotRecordsError, read_robot_records

    path = _robot_records(tmp_path / "robot.mcap")
    settings, episodes = read_robot_records(path)
    assert settings["cell"] == 1.0 and len(episodes) == 3
    assert episodes[2]["pictures"][0]["image"].shape == (8, 8, 3)
    data = path.read_bytes()
    if damage == "cut":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(data[:200] + bytes(range(256)) * 8 + data[-100:])
    else:  # an MCAP file without the robot's metadata
        from mcap.writer import Writer

        with open(path, "wb") as f:
            w = Writer(f)
            w.start()
            w.finish()
    with pytest.raises(RobotRecordsError, match=str(path)):
        read_robot_records(path)


def test_the_report_names_a_damaged_robot_record_file(tmp_path):
    from types import SimpleNamespace

    from pipeline.report.experiments import ReportInputError
    from pipeline.report.robot import sim_time_per_run

    path = _robot_records(tmp_path / "robot.mcap")
    cell = SimpleNamespace(path=tmp_path / "records.mcap")
    assert sim_time_per_run(cell).tolist() == [4.5]  # run 0: three episodes of 1.5 s
    path.write_bytes(path.read_bytes()[:300])
    with pytest.raises(ReportInputError, match="robot.mcap: cannot read the robot's records"):
        sim_time_per_run(cell)


@pytest.mark.parametrize(
    "overrides,message",
    [
        (
            ["method=shield", "robot.cell=0.8"],
            "config key 'robot.cell': read only with world=robot3d",
        ),
        (["method=shield", "world=mars"], "world"),
        (["method=shield", "world=robot3d", "robot.timestep=0.03"], "timestep"),
    ],
)
def test_robot_config_is_applied_or_refused(tmp_path, overrides, message):
    from pipeline.errors import ConfigError
    from pipeline.stages._common import run_stage

    with pytest.raises((ConfigError, ValueError), match=message):
        run_stage(
            "trials", [*overrides, "runs=1", "episodes=1", f"out={tmp_path}", "progress=false"]
        )


def test_an_experiment_mixing_worlds_shares_the_recogniser_but_wraps_it_for_the_robot():
    from pipeline.stages._cell_plan import experiment_cells
    from pipeline.stages._cell_run import make_recogniser
    from pipeline.stages._common import load_config

    cfg = load_config("trials", ["+experiment=robot3d", "recogniser=oracle"])
    cells = experiment_cells(cfg, ["+experiment=robot3d", "recogniser=oracle"])
    built = {}
    grid = make_recogniser(cells["fewshot_5x5_grid"], built=built)
    robot = make_recogniser(cells["fewshot_5x5_robot3d"], built=built)
    assert callable(getattr(robot, "live_scores", None)) and robot is not grid
    assert {c.world for c in cells.values()} == {"grid", "robot3d"}


@pytest.mark.slow  # 10-20 s
def test_the_replay_stage_replays_a_robot_cell_in_3d(tmp_path):
    import rerun.chunk

    from pipeline.errors import ConfigError
    from pipeline.stages._common import run_stage

    cell = tmp_path / "cell"
    run_stage("trials", ["method=fewshot", "world=robot3d", "recogniser=oracle", "runs=1",
                         "episodes=1", "robot.threshold=1.0", f"out={cell}", "progress=false"])  # fmt: skip
    replay = ["run=0", "viewer=none"]
    rrd = run_stage("replay", [f"file={cell / 'records.mcap'}", *replay, "episode=0",
                               f"out={tmp_path / 'replay.rrd'}"])  # fmt: skip
    chunks = rerun.chunk.RrdReader(str(rrd)).stream().to_chunks()
    paths = {str(c.entity_path) for c in chunks}
    assert {"/robot/path", "/robot/body", "/camera/picture", "/camera/scores"} <= paths
    assert any(p.startswith("/scene/obstacle") for p in paths)
    assert any(p.startswith("/scene/wall") for p in paths)
    # robot.mcap names the same cell; without an episode, the first with a recognition
    again = run_stage("replay", [f"file={cell / 'robot.mcap'}", *replay,
                                 f"out={tmp_path / 'again.rrd'}"])  # fmt: skip
    again_chunks = rerun.chunk.RrdReader(str(again)).stream().to_chunks()
    assert sorted(str(c.entity_path) for c in again_chunks) == sorted(
        str(c.entity_path) for c in chunks
    )  # the same episode (an .rrd holds wall-clock log times: not the same bytes)
    with pytest.raises(ConfigError, match="'run'/'episode': .*no run 0 episode 5"):
        run_stage("replay", [f"file={cell / 'records.mcap'}", *replay, "episode=5",
                             f"out={tmp_path / 'x.rrd'}"])  # fmt: skip
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "records.mcap").write_bytes((cell / "records.mcap").read_bytes())
    (bad / "robot.mcap").write_bytes((cell / "robot.mcap").read_bytes()[:3000])
    with pytest.raises(ConfigError, match="'file': .*robot.mcap: cannot read the robot's records"):
        run_stage("replay", [f"file={bad / 'records.mcap'}", *replay, "episode=0",
                             f"out={tmp_path / 'z.rrd'}"])  # fmt: skip
    with pytest.raises(ConfigError, match="'whole_run'"):
        run_stage("replay", [f"file={cell / 'records.mcap'}", *replay, "whole_run=true",
                             f"out={tmp_path / 'y.rrd'}"])  # fmt: skip
    assert not any((tmp_path / n).exists() for n in ("x.rrd", "y.rrd", "z.rrd"))


@pytest.mark.slow  # 30-60 s: 20 small cells and a report
def test_report_section_on_a_simulated_robot(tmp_path):
    import yaml

    from pipeline.conf import conf_dir
    from pipeline.stages._common import run_stage

    cells = yaml.safe_load((conf_dir("experiment") / "robot3d.yaml").read_text())["experiment"]
    # the Prototypical Network's cells need rendered pictures, which a fresh clone lacks
    drop = [f"~experiment.cells.{name}" for name, cell in cells["cells"].items()
            if cell.get("recogniser_group") == "protonet"]  # fmt: skip
    assert drop
    runs = tmp_path / "runs"
    run_stage("trials", ["+experiment=robot3d", "recogniser=oracle", "runs=2", "episodes=2",
                         "workers=1", f"out={runs / 'robot3d'}", "progress=false", *drop])  # fmt: skip
    run_stage("report", [f"runs_dir={runs}", f"out={tmp_path / 'report'}", "allow_missing=true"])
    text = (tmp_path / "report" / "index.md").read_text()
    assert "On a simulated robot" in text
    table = (tmp_path / "report" / "tables" / "robot3d.csv").read_text()
    assert "collisions, robot (MuJoCo)" in table and "collisions, grid" in table
    accuracy = (tmp_path / "report" / "tables" / "robot3d_recognition.csv").read_text()
    assert "oracle: live pictures (robot)" in accuracy and "1.00" in accuracy  # the oracle
    assert (tmp_path / "report" / "tables" / "robot3d_robot_time.csv").exists()
