import numpy as np
import pytest
from fakes import ListSink, TableRecogniser, always_right, always_wrong

from pipeline.rl.agents import TabularAgent, run_episode
from pipeline.rl.codes import StepFlag
from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import get_method, method_names
from pipeline.rl.rng import run_seeds
from pipeline.rl.runner import run_trials
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import load_layout

MAZE = load_layout("5x5")


def collisions_by(sink, run, key):
    seen = {}
    for ep in sink.by_run(run):
        hit = (ep["flags"] & StepFlag.collided) != 0
        for s, a in zip(ep["states"][hit], ep["actions"][hit]):
            k = key(int(s), int(a))
            seen[k] = seen.get(k, 0) + 1
    return seen


def test_shield_never_collides_twice_from_the_same_pair():
    sink = ListSink()
    result = run_trials(
        MAZE, get_method("shield"), runs=4, episodes=60, seed=1, sink=sink, progress=False
    )
    for run in range(4):
        seen = collisions_by(sink, run, lambda s, a: (s, a))
        assert seen and max(seen.values()) == 1
        assert sum(seen.values()) == result.collisions[run].sum()


def test_ssrl_never_collides_twice_with_the_same_obstacle():
    g = build_geometry(MAZE)
    sink = ListSink()
    run_trials(MAZE, get_method("ssrl"), runs=4, episodes=60, seed=2, sink=sink, progress=False)
    for run in range(4):
        seen = collisions_by(sink, run, lambda s, a: int(g.obstacle[s, a]))
        assert seen and max(seen.values()) == 1


def test_fewshot_with_a_perfect_recogniser_never_collides():
    result = run_trials(
        MAZE,
        get_method("fewshot"),
        runs=3,
        episodes=40,
        seed=3,
        recogniser=always_right(),
        progress=False,
    )
    assert result.collisions.sum() == 0 and result.prevented.sum() > 0


def test_fewshot_with_a_blind_recogniser_collides_once_per_pair_like_the_shield():
    blind = run_trials(
        MAZE,
        get_method("fewshot"),
        runs=3,
        episodes=40,
        seed=3,
        recogniser=always_wrong(),
        progress=False,
    )
    assert blind.prevented.sum() == 0
    # every collision is a distinct (s, a): never more than the dangerous pairs
    assert (blind.collisions.sum(axis=1) <= len(build_geometry(MAZE).dangerous_pairs)).all()


def test_dynamic_support_set_learns_from_every_misrecognition():
    rec = TableRecogniser(correct=(), dynamic=True)
    sink = ListSink()
    result = run_trials(
        MAZE,
        get_method("fewshot_dss"),
        runs=2,
        episodes=30,
        seed=4,
        recogniser=rec,
        sink=sink,
        progress=False,
    )
    learnt = [s for s in sink.substitutions if s["picture"] >= 0]
    assert len(rec.learnt) == result.collisions.sum() == len(learnt)
    # one record of the initial support set per run, then its accuracy rises with every substitution
    starts = [s for s in sink.substitutions if s["picture"] < 0]
    assert [s["run"] for s in starts] == [0, 1] and all(
        s["support_accuracy"] == 0.0 for s in starts
    )
    for run in range(2):
        acc = [s["support_accuracy"] for s in sink.substitutions if s["run"] == run]
        assert (
            acc == sorted(acc)
            and acc[-1] == len(set(x["picture"] for x in learnt if x["run"] == run)) / 40
        )
    # after learning a picture the robot recognises it: no picture collides twice in a run
    for run in range(2):
        pics = [
            e["recognitions"]["picture"][
                e["recognitions"]["predicted"] != e["recognitions"]["true"]
            ]
            for e in sink.by_run(run)
        ]
        pics = np.concatenate(pics)
        assert len(pics) == len(set(pics.tolist()))


def test_same_seed_same_results_and_runs_do_not_depend_on_the_batch():
    a = run_trials(MAZE, get_method("qlearning"), runs=5, episodes=50, seed=7, progress=False)
    b = run_trials(MAZE, get_method("qlearning"), runs=5, episodes=50, seed=7, progress=False)
    c = run_trials(MAZE, get_method("qlearning"), runs=2, episodes=50, seed=7, progress=False)
    d = run_trials(MAZE, get_method("qlearning"), runs=5, episodes=50, seed=8, progress=False)
    assert a.summary() == b.summary()
    np.testing.assert_array_equal(a.steps[:2], c.steps)
    assert not np.array_equal(a.steps, d.steps)


@pytest.mark.parametrize("shared", [False, True])
def test_finished_episodes_reach_the_sink_every_500_and_chunks_change_no_result(shared):
    """A recording sink gets every run's finished episodes every EMIT_EVERY (500) episodes (what a
    killed run keeps, docs/reliability.md), with a step trace too; chunking changes no result."""
    method, sink = get_method("fewshot_dss"), ListSink()
    kw = dict(runs=2, episodes=1100, seed=3, progress=False, shared_support=shared)
    chunked = run_trials(MAZE, method, recogniser=always_wrong(), sink=sink, **kw)
    got = sorted((int(b["run"]), int(b["episode"][0]), int(b["episode"][-1])) for b in sink.batches)
    assert got == [(r, a, b) for r in (0, 1) for a, b in ((0, 499), (500, 999), (1000, 1099))]
    whole = run_trials(MAZE, method, recogniser=always_wrong(), chunk_episodes=1100, **kw)
    assert chunked.summary() == whole.summary()
    np.testing.assert_array_equal(chunked.steps, whole.steps)


def test_summary_fields():
    s = run_trials(MAZE, get_method("ssrl"), runs=3, episodes=80, seed=0, progress=False).summary()
    assert s["n_runs"] == 3 and len(s["runs"]) == 3
    assert set(s["runs"][0]) >= {"collisions", "steps", "converged_episode"}
    assert s["collisions"]["mean"] == pytest.approx(np.mean([r["collisions"] for r in s["runs"]]))


@pytest.mark.parametrize("name", method_names())
def test_gym_and_batched_runner_give_identical_trajectories(name):
    method = get_method(name)
    seed, episodes = 11, 25
    recs = {}
    if method.uses_recogniser:
        recs = {
            "runner": TableRecogniser(correct=range(0, 40, 2), dynamic=method.dynamic_support),
            "gym": TableRecogniser(correct=range(0, 40, 2), dynamic=method.dynamic_support),
        }
    sink = ListSink()
    run_trials(
        MAZE,
        method,
        runs=1,
        episodes=episodes,
        seed=seed,
        sink=sink,
        recogniser=recs.get("runner"),
        progress=False,
    )
    env = SafeNavigationEnv(MAZE, method, recogniser=recs.get("gym"))
    agent = TabularAgent(method, MAZE.n_cells, run_seeds(seed, 0).agent)
    for ep, recorded in enumerate(sink.by_run(0)):
        gym_ep = run_episode(env, agent, seed=seed if ep == 0 else None)
        for key in ("states", "actions", "rewards", "flags"):
            np.testing.assert_array_equal(gym_ep[key], recorded[key], err_msg=f"episode {ep} {key}")


def test_recorded_relation_scores_are_the_recognisers_at_the_time_of_each_recognition():
    """Scores are asked for once per recognition, before a collision teaches the recogniser: with the
    fixed-accuracy recogniser (one-hot scores) every recorded row is one-hot on the recorded prediction,
    across the runner's batches and trace hand-overs (a small trace forces many)."""
    from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser

    sink = ListSink()
    run_trials(
        load_layout("7x7"),
        get_method("fewshot_dss"),
        runs=3,
        episodes=80,
        seed=4,
        sink=sink,
        recogniser=FixedAccuracyRecogniser(p=0.4, learn=True, substitution_way=1),
        progress=False,
        trace_capacity=256,
    )
    rec = [b["recognitions"] for b in sink.batches if len(b["recognitions"]["step"])]
    assert len(rec) > 3 and any(s["picture"] >= 0 for s in sink.substitutions)
    scores = np.concatenate([r["scores"] for r in rec])
    predicted = np.concatenate([r["predicted"] for r in rec])
    assert scores.shape == (len(predicted), 5) and (scores.sum(axis=1) == 1).all()
    np.testing.assert_array_equal(scores.argmax(axis=1), predicted)


def test_a_sink_without_steps_gets_the_same_episodes_without_the_step_rows():
    """``records_steps = False`` (``record=episodes``): no step trace is kept; the trial's outcome and every
    per-episode field handed over are those of a full recording."""
    from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser

    def trial(sink):
        return run_trials(
            load_layout("7x7"),
            get_method("fewshot_dss"),
            runs=3,
            episodes=50,
            seed=2,
            sink=sink,
            recogniser=FixedAccuracyRecogniser(p=0.5, substitution_way=1),
            progress=False,
            chunk_episodes=20,
        )

    full, lean = ListSink(), ListSink()
    lean.records_steps = False
    a, b = trial(full), trial(lean)
    np.testing.assert_array_equal(a.collisions, b.collisions)
    assert full.substitutions == lean.substitutions
    assert all(len(ep["states"]) == 0 for ep in lean.all_episodes)
    key = lambda e: (e["run"], e["episode"])  # noqa: E731
    for f, g in zip(sorted(full.all_episodes, key=key), sorted(lean.all_episodes, key=key)):
        assert key(f) == key(g) and f["steps"] == g["steps"] > 0 and f["summary"] == g["summary"]
        for sub in ("recognitions", "unsafe_added"):
            assert f[sub].keys() == g[sub].keys()
            for k in f[sub]:
                np.testing.assert_array_equal(f[sub][k], g[sub][k])
