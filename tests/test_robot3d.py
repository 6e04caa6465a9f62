"""The camera robot in MuJoCo inside the one runner (issues 30 and 38): the Burger's limits, the
range sensor, the motion table against the full world, live pictures, the decision rules, the
robot's outcomes against the grid's, the Gymnasium ids and bad input."""

from __future__ import annotations

import signal

import numpy as np
import pytest

from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser
from pipeline.rl.methods import get_method
from pipeline.rl.rules import Rule
from pipeline.rl.run_world import GRID, run_placement
from pipeline.rl.runner import run_trials
from pipeline.robot.live import live
from pipeline.robot.live_world import PICTURE_SIZE, RobotSettings, RobotWorld, rendered_run
from pipeline.robot.model import MAX_SPEED, MAX_TURN
from pipeline.robot.motion import (
    QUARTERS,
    PathBuilder,
    drive_key,
    episode_path,
    motion_table,
    relative_orientation,
)
from pipeline.robot.sim import HEADINGS, RobotSim, wheel_limited
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import load_layout
from pipeline.world.pictures import N_PHYSICAL_OBSTACLES

#: Self-recovery's stated tolerance (docs/robot3d.md): back within 2 cm of the previous centre.
RECOVERY_TOLERANCE_MM = 20


@pytest.fixture(scope="module")
def table():
    return motion_table(1.0, 0.02)


def test_wheel_limits_keep_the_burgers_speeds():
    v, omega = wheel_limited(5.0, 10.0)
    assert abs(v) <= MAX_SPEED + 1e-9 and abs(omega) <= MAX_TURN + 1e-9
    assert wheel_limited(0.1, 0.0) == pytest.approx((0.1, 0.0))


def test_motion_table_free_drive_arrives_and_every_obstacle_is_one_contact(table):
    free = table["drives"]["free"]["poses"]
    assert abs(free[-1][0] - 1000) <= 10 and abs(free[-1][1]) <= 5  # the next centre, +-1 cm
    assert len(table["drives"]) == 1 + 4 * N_PHYSICAL_OBSTACLES
    for key, drive in table["drives"].items():
        if key == "free":
            continue
        assert drive["contact"] is not None and 0 < drive["stopped"] < len(drive["poses"])
        x, y, _ = drive["poses"][-1]  # self-recovery drove it back to the centre it left
        assert np.hypot(x, y) <= RECOVERY_TOLERANCE_MM
        assert 0 < drive["contact"][0] < 1000  # the contact lies toward the neighbour
    for k, turn in enumerate(table["turns"]):
        assert (len(turn) == 0) == (k == 0)
        if k:
            want = np.angle(np.exp(1j * k * np.pi / 2))
            assert abs(np.angle(np.exp(1j * (turn[-1][2] / 1000 - want)))) < 0.01


def test_the_range_sensor_agrees_with_the_layout_and_pictures_are_84_px():
    layout = load_layout("5x5")
    got = rendered_run(layout.rows, 11, 0, RobotSettings())  # raises where the sensor disagrees
    geometry = build_geometry(layout)
    assert len(got.pairs) == int((geometry.obstacle >= 0).sum())
    assert got.images.shape[1:] == (PICTURE_SIZE, PICTURE_SIZE, 3) and got.images.std() > 10


def test_the_motion_table_is_the_full_worlds_physics_to_the_millimetre(table):
    """The cached transition (the table, simulated once in its own frame) against the uncached
    one (the robot driven in the run's whole maze, where it stands): the same poses to 1 mm."""
    layout = load_layout("5x5")
    geometry = build_geometry(layout)
    placement = run_placement(geometry, 0, 0)
    sim = RobotSim(layout, placement)
    obstacles = placement.as_records(layout.obstacles)
    checked = 0
    for s in range(layout.n_cells):
        if s in layout.obstacles:
            continue
        for a in range(4):
            if not sim.inside(s, a):
                continue
            before = (a + 1) % 4  # facing a quarter turn away from the move
            path = PathBuilder(table, layout, obstacles)
            path.turn(s, before)
            since = path.ticks
            path.move(s, a, 2 | 4 if geometry.obstacle[s, a] >= 0 else 0)  # collided, recovered
            sim.place(s, before)
            poses = sim.turn(a)
            sim.place(s, a)  # settled after the turn: the robot re-localises
            drive, hit, _ = sim.drive(a, recover=True)
            assert (hit is not None) == (geometry.obstacle[s, a] >= 0), (s, a)
            full = np.array([[x, y, np.angle(np.exp(1j * t))] for x, y, t in poses + drive])
            table_poses = path.poses(since)[:, 1:]
            assert full.shape == table_poses.shape
            assert np.abs(full[:, :2] - table_poses[:, :2]).max() <= 1.01e-3
            assert np.abs(np.angle(np.exp(1j * (full[:, 2] - table_poses[:, 2])))).max() <= 1.01e-3
            checked += 1
    sim.close()
    assert checked > 30


def test_relative_orientation_turns_the_obstacle_into_the_moves_frame():
    assert [relative_orientation(0, a) for a in range(4)] == [1, 0, 3, 2]
    assert [QUARTERS[a] for a in range(4)] == [1, 0, -1, 2]
    assert drive_key(None) == "free" and drive_key(7, 3) == "p7_o3"


def _trial(world_name: str, method: str, recogniser=None, rule=Rule.paper, runs=3, episodes=40):
    layout = load_layout("5x5")
    spec = get_method(method)
    world = GRID
    if world_name == "robot3d":
        world = RobotWorld(layout, RobotSettings(), live_pictures=spec.uses_recogniser)
        geometry = build_geometry(layout)
        for r in range(runs):
            world.run_world(geometry, 0, r)
        recogniser = live(recogniser, world) if recogniser is not None else None
    return run_trials(
        layout,
        spec,
        runs,
        episodes,
        0,
        recogniser=recogniser,
        world=world,
        rule=rule,
        progress=False,
    )


@pytest.mark.parametrize("method", ["shield", "ssrl", "fewshot", "fewshot_dss"])
def test_with_a_model_of_recognition_the_robot_moves_as_the_grid(method):
    """fixed_accuracy (p = 0.5) answers a live picture as its face's query picture: under the
    paper's rule the robot's outcomes are the grid's, run by run and episode by episode."""
    model = FixedAccuracyRecogniser(p=0.5) if get_method(method).uses_recogniser else None
    robot = _trial("robot3d", method, model)
    grid = _trial("grid", method, FixedAccuracyRecogniser(p=0.5) if model else None)
    for field in ("steps", "collisions", "prevented", "returns"):
        assert np.array_equal(getattr(robot, field), getattr(grid, field)), field


def test_the_range_rule_never_collides_and_open_set_with_a_model_is_the_range_rule():
    ranged = _trial("robot3d", "fewshot", FixedAccuracyRecogniser(p=0.3), Rule.range)
    assert ranged.collisions.sum() == 0 and ranged.prevented.sum() > 0
    open_set = _trial("robot3d", "fewshot", FixedAccuracyRecogniser(p=0.3), Rule.open_set)
    assert np.array_equal(open_set.collisions, ranged.collisions)  # one-hot scores: always sure
    paper = _trial("robot3d", "fewshot", FixedAccuracyRecogniser(p=0.3), Rule.paper)
    assert paper.collisions.sum() > 0


def test_episode_path_starts_on_the_start_cell_and_marks_every_picture_and_contact(table):
    layout = load_layout("5x5")
    geometry = build_geometry(layout)
    obstacles = run_placement(geometry, 0, 0).as_records(layout.obstacles)
    s = layout.start
    a = int(np.flatnonzero(geometry.obstacle[s] >= 0)[0])
    free = int(np.flatnonzero((geometry.obstacle[s] < 0) & (geometry.next_cell[s] != s))[0])
    steps = [(s, a, 2 | 4), (s, free, 0)]  # collided and recovered, then a free move
    path = episode_path(table, layout, obstacles, steps, [{"step": 0, "action": a}])
    assert path["poses"][0, 0] == 0.0 and len(path["pictures"]) == 1 and len(path["contacts"]) == 1
    centre = np.array([(s % 5 - 2) * 1.0, (2 - s // 5) * 1.0])
    assert np.allclose(path["poses"][0, 1:3], centre)
    assert np.all(np.diff(path["poses"][:, 0]) == pytest.approx(0.1))


def test_gymnasium_ids_check_env_six_values_and_live_pictures():
    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pipeline  # noqa: F401  (registers the ids)
    from pipeline.envs import SixValueStep

    env = gymnasium.make(
        "SafeNav3D-5x5-v0",
        method="fewshot_dss",
        recogniser="fixed_accuracy",
        recogniser_options={"p": 0.5},
        render_mode="rgb_array",
        max_episode_steps=-1,
    )
    check_env(env.unwrapped, skip_render_check=True)
    six = SixValueStep(env)
    _, info = six.reset(seed=0)
    seen = 0
    for i in range(80):
        mask = np.flatnonzero(info["action_mask"])
        _, _, cost, terminated, truncated, info = six.step(int(mask[i % len(mask)]))
        assert cost == float(info["collided"])
        if info["camera"] is not None:
            seen += 1
            assert info["camera"].shape == (PICTURE_SIZE, PICTURE_SIZE, 3)
            assert len(info["scores"]) == 5
        if terminated or truncated:
            break
    assert seen > 0
    assert six.render().shape == (480, 640, 3)
    env.close()


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"timestep": 0}, "timestep=0"),
        ({"timestep": 1e-9}, "0.001-0.05"),
        ({"cell": float("inf")}, "cell=inf"),
        ({"render_mode": "human"}, "render_mode='human'"),
    ],
)
def test_the_gymnasium_robot_refuses_what_it_cannot_run(kwargs, message):
    import gymnasium

    import pipeline  # noqa: F401

    with pytest.raises(ValueError, match=message):
        gymnasium.make("SafeNav3D-5x5-v0", **kwargs)


@pytest.mark.parametrize(
    "overrides,message",
    [
        (["method=shield", "robot.cell=0.8"], "config key 'robot.cell': read only with world"),
        (["method=shield", "world=mars"], "world"),
        (["method=shield", "world=robot3d", "robot.timestep=0.03"], "timestep"),
        (["method=shield", "world=robot3d", "robot.timestep=1e-9"], "robot.timestep"),
        (["method=shield", "world=robot3d", "robot.cell=inf"], "robot.cell"),
        (["method=shield", "world=robot3d", "robot.cell=10"], "robot.cell"),
        (["method=shield", "world=robot3d", "robot.cell=0.05"], "robot.cell"),
        (["method=shield", "rule=open_set"], "config key 'rule': read only by methods"),
        (["method=fewshot", "recogniser=oracle", "threshold=0.9"], "rule=open_set"),
        (["method=fewshot", "recogniser=oracle", "rule=maybe"], "rule"),
        (
            ["method=fewshot", "recogniser=oracle", "world=robot3d", "maze=random:100x100:5000:0"],
            "config key 'maze': world=robot3d: maze random:100x100:5000:0 has 5,000 obstacles",
        ),
    ],
)
def test_robot_and_rule_config_is_applied_or_refused(tmp_path, overrides, message):
    from pipeline.errors import ConfigError
    from pipeline.stages import run_stage

    with pytest.raises((ConfigError, ValueError), match=message):
        run_stage(
            "trials", [*overrides, "runs=1", "episodes=1", f"out={tmp_path}", "progress=false"]
        )
    assert not any(tmp_path.iterdir())


def test_an_experiments_profile_sets_its_scale():
    """robot3d declares no runs or episodes of its own: ``profile=smoke`` is 3 x 20."""
    from pipeline.config.compose import load_config

    cfg = load_config("trials", ["+experiment=robot3d", "profile=smoke"])
    assert (cfg.runs, cfg.episodes) == (3, 20)
    assert load_config("trials", ["+experiment=robot3d"]).runs == 100


def test_a_robot_cell_is_one_record_file_that_the_records_tool_reads(tmp_path):
    import subprocess
    import sys

    from pipeline.records import read_records
    from pipeline.stages import run_stage

    out = tmp_path / "cell"
    run_stage(
        "trials",
        [
            "method=fewshot_dss",
            "world=robot3d",
            "recogniser=fixed_accuracy",
            "recogniser.p=0.5",
            "runs=2",
            "episodes=5",
            f"out={out}",
            "progress=false",
        ],
    )
    assert sorted(p.name for p in out.iterdir()) == ["records.mcap", "summary.json"]
    records = read_records(out / "records.mcap")
    robot = records.meta.info["robot"]
    assert robot["cell"] == 1.0 and len(robot["drives"]) == 41
    assert records.meta.config["world"] == "robot3d"
    shown = subprocess.run(
        [sys.executable, "-m", "pipeline.records", str(out)], capture_output=True
    )
    assert shown.returncode == 0, shown.stderr


def test_cached_and_uncached_runs_give_the_same_record_bytes(tmp_path):
    """Live pictures, embeddings and the motion table are kept per process; a cell run with every
    cache cleared writes the same bytes as one run after another cell filled them."""
    from pipeline.fewshot import support_recogniser
    from pipeline.robot import live_world
    from pipeline.stages import run_stage

    args = [
        "method=fewshot_dss",
        "world=robot3d",
        "recogniser=fixed_accuracy",
        "runs=2",
        "episodes=5",
        "progress=false",
    ]
    out = f"out={tmp_path / 'cell'}"
    run_stage("trials", [*args, out, "rule=range"])
    run_stage("trials", [*args, out, "overwrite=true"])
    warm = (tmp_path / "cell" / "records.mcap").read_bytes()
    live_world.rendered_run.cache_clear()
    live_world.run_pngs.cache_clear()
    motion_table.cache_clear()
    support_recogniser._EMBEDDINGS.clear()
    run_stage("trials", [*args, out, "overwrite=true"])
    assert warm == (tmp_path / "cell" / "records.mcap").read_bytes()


@pytest.fixture(scope="module", params=["relation_net", "protonet"])
def live_network(request, tmp_path_factory):
    """An untrained few-shot network on a synthetic picture set: what a fresh clone has (no
    rendered pictures); the test checks the plumbing, not the accuracy."""
    from fakes import untrained_network

    from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser

    cls = {"relation_net": RelationRecogniser, "protonet": ProtoRecogniser}[request.param]
    root = tmp_path_factory.mktemp(request.param)
    ckpt, _ = untrained_network(root, request.param)
    return cls.from_files(ckpt, root / "images", substitution_way=1)


def test_few_shot_networks_score_live_pictures_and_substitute_them(live_network):
    layout = load_layout("5x5")
    world = RobotWorld(layout, RobotSettings())
    run = world.run_world(build_geometry(layout), 0, 0)
    rec = live(live_network, world)
    rec.start_run(0, 5)
    predicted = rec.predictions(0)
    assert predicted.shape == (world.n_pictures,) and set(predicted[run.seen]) <= set(range(5))
    scores = rec.scores(0, run.seen)
    assert scores.shape == (len(run.seen), 5) and np.all((scores >= 0) & (scores <= 1))
    picture = int(run.seen[0])
    category = int(world.picture_category[picture])
    position = rec.learn_from_collision(0, picture, category)
    assert 0 <= position < 5
    first, own, _ = rec._runs[0]  # the network over run 0's own live pictures
    assert own.support_members(0)[category, position] == picture - first


def test_a_recogniser_without_the_protocol_is_refused():
    layout = load_layout("5x5")
    with pytest.raises(ValueError, match="cannot recognise live pictures"):
        live(object(), RobotWorld(layout, RobotSettings()))


def test_settings_are_checked_where_the_robot_world_is_built():
    for cell, timestep in ((float("nan"), 0.02), (0.05, 0.02), (1.0, 0.03), (1.0, 0.0)):
        with pytest.raises(ValueError):
            RobotSettings(cell, timestep)
    assert HEADINGS[1] == 0.0


@pytest.mark.filterwarnings("ignore::pipeline.records.RecordsWarning")  # a .partial, as expected
@pytest.mark.parametrize(
    "sig",
    [  # about 15-20 s each, `make test-slow`; the grid's runs test the signals by default
        # (tests/faults/test_kills.py) and the robot's records go through the same writer
        pytest.param(sig, marks=pytest.mark.slow)
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGKILL)
    ],
)
def test_a_killed_robot_run_keeps_what_it_handed_over_poses_and_pictures_included(tmp_path, sig):
    """The robot's records are the one writer's: a killed robot run keeps every episode handed
    over two seconds before the signal, with its live pictures and its motion table (its poses)."""
    import subprocess
    import sys
    import time

    from entry import ROOT

    from pipeline.records import read_records

    args = [
        "method=fewshot_dss",
        "world=robot3d",
        "recogniser=fixed_accuracy",
        "runs=8",
        "episodes=2000000",  # long enough to be running when the signal comes
        "flush_every=100000",
        "progress=false",
        f"out={tmp_path}",
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "pipeline", "trials", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    t0 = time.time()
    while not list(tmp_path.glob(".staging-*/records.mcap.partial")):
        assert time.time() - t0 < 60 and proc.poll() is None, proc.stderr and proc.stderr.read()
        time.sleep(0.1)
    time.sleep(3.0)  # past the writer's 2 s flush: what it had by then is on disk
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    partial = next(tmp_path.glob(".staging-*/records.mcap.partial"))
    records = read_records(partial)
    assert len(records.episodes) > 0 and len(records.recognitions) > 0
    assert set(records.recognitions["picture"]) <= set(records.meta.pictures)
    table = records.meta.info["robot"]
    layout = load_layout(records.meta.config["maze"])
    first = records.steps[(records.steps["run"] == 0) & (records.steps["episode"] == 0)]
    steps = first[["state", "action", "flags"]].to_numpy()
    looks = records.recognitions[
        (records.recognitions["run"] == 0) & (records.recognitions["episode"] == 0)
    ]
    path = episode_path(table, layout, records.meta.obstacles[0], steps, looks.to_dict("records"))
    assert len(path["poses"]) > len(steps) and len(path["pictures"]) == len(looks)


def test_a_rule_every_reading_cell_pins_is_refused_not_ignored(tmp_path):
    """robot3d pins the rule of every cell that reads one (the few-shot cells; the shield and SSRL
    read none): ``rule=`` on the command line would change nothing."""
    from pipeline.errors import ConfigError
    from pipeline.stages import run_stage

    with pytest.raises(ConfigError, match="config key 'rule': every cell of experiment robot3d"):
        run_stage("trials", ["+experiment=robot3d", "rule=open_set", f"out={tmp_path}"])
