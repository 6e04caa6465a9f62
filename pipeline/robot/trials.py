"""Trials with the robot (issue 30): independent runs of a method, each episode through
:class:`pipeline.robot.env.SafeNavigation3DEnv`, handed to the same ``EpisodeSink`` as the grid's
runner (``pipeline/rl/sink.py``) and returned as the same :class:`~pipeline.rl.trial_result.TrialResult`.

Run ``r`` takes its obstacle placement, its agent's stream and its recogniser seed from
``run_seeds(seed, r)``, as the grid's runner does, so a robot cell and the grid cell with the same
seed meet the same obstacles. The agent is ``agents.TabularAgent`` (the kernel's policy and update
functions, in the kernel's order), so the methods run unchanged.

What only the robot has goes to ``robot_sink.episode(...)`` (:mod:`pipeline.robot.records`): the
pose at 10 Hz, every classified live picture with its scores, each collision's contact point and
the simulated time of the episode. A live picture is not a query picture: its recognition row says
``picture = -1``, ``predicted`` the category its scores name (-1 for none); ``true`` is the world's
category there, kept for the accuracy (a network never decides on it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.rl.agents import TabularAgent, run_episode
from pipeline.rl.codes import StepFlag
from pipeline.rl.methods import MethodSpec
from pipeline.rl.policy import greedy_path_is_optimal
from pipeline.rl.rng import run_seeds
from pipeline.rl.trial_result import TrialResult
from pipeline.robot.env import SafeNavigation3DEnv
from pipeline.robot.world import DEFAULT_CELL
from pipeline.world.layout import Layout, shortest_path_length
from pipeline.world.pictures import N_CATEGORIES


@dataclass(frozen=True)
class RobotSettings:
    """The robot world's settings (``pipeline/conf/world/robot3d.yaml``)."""

    cell: float = DEFAULT_CELL
    timestep: float = 0.02
    threshold: float = 0.5


def _episode(env: SafeNavigation3DEnv, agent: TabularAgent, seed: int | None):
    """One episode; the run_episode arrays and every step's (state, action, info)."""
    steps, step = [], env.step

    def logged(a):
        s = env.state
        out = step(a)
        steps.append((s, int(a), out[4]))
        return out

    env.step = logged
    try:
        arrays = run_episode(env, agent, seed=seed)
    finally:
        env.step = step
    return arrays, steps


def _batch(run: int, ep: int, arrays: dict, steps: list, agent, env) -> tuple[dict, dict]:
    """The sink's batch of one episode (pipeline/rl/sink.py) and the robot's own record of it."""
    rec = {k: [] for k in ("episode", "step", "state", "action", "picture", "predicted", "true")}
    rec_scores, add, executed = (
        [],
        {k: [] for k in ("episode", "step", "state", "action", "source")},
        0,
    )
    poses, pictures, contacts, sim_time = [], [], [], 0.0
    for s, a, info in steps:
        started = sim_time
        sim_time += info["sim_time"]
        poses += info["poses"]
        if info["camera"] is not None:
            truth = env._truth_at(env._target(s, a))
            scores = np.asarray(info["scores"], np.float32)
            for key, v in zip(rec, (ep, executed, s, a, -1, _named(scores), truth)):
                rec[key].append(v)
            rec_scores.append(scores)
            pictures.append({"step": executed, "time": round(started, 6), "state": s, "action": a, "image": info["camera"],
                             "scores": scores, "true": truth, "prevented": info["prevented"],
                             "substituted": info["substituted"]})  # fmt: skip
        for cell, action, source in info["added"]:
            for key, v in zip(add, (ep, executed, cell, action, source)):
                add[key].append(v)
        if info["contact"] is not None:
            contacts.append({"step": executed, "point": info["contact"], "time": sim_time})
        if not info["prevented"]:
            executed += 1
    g, layout = env.geometry, env.layout
    flags = arrays["flags"]
    dtypes = {"episode": np.int32, "step": np.int32, "state": np.int32, "action": np.int8,
              "picture": np.int16, "predicted": np.int8, "true": np.int8, "source": np.int8}  # fmt: skip
    summary = {
        "collisions": np.array([sum(i["collided"] for *_, i in steps)], np.int32),
        "return_": np.array([arrays["rewards"].sum()], np.float32),
        "reached_goal": np.array([bool(flags.size and flags[-1] & StepFlag.goal)]),
        "prevented": np.array([sum(i["prevented"] for *_, i in steps)], np.int32),
        "epsilon": np.array([agent.epsilon], np.float32),
        "greedy_optimal": np.array(
            [
                greedy_path_is_optimal(
                    agent.q,
                    env.unsafe,
                    g.next_cell,
                    g.obstacle,
                    layout.start,
                    layout.goal,
                    shortest_path_length(layout),
                )
            ]  # fmt: skip
        ),
    }
    batch = dict(
        run=run,
        episode=np.array([ep], np.int32),
        steps=np.array([len(arrays["states"])], np.int32),
        states=arrays["states"],
        actions=arrays["actions"],
        rewards=arrays["rewards"],
        flags=arrays["flags"],
        recognitions={
            **{k: np.array(v, dtypes[k]) for k, v in rec.items()},
            "scores": np.array(rec_scores, np.float32).reshape(-1, N_CATEGORIES),
        },
        unsafe_added={k: np.array(v, dtypes[k]) for k, v in add.items()},
        summary=summary,
    )
    robot = {"run": run, "episode": ep, "sim_time": round(sim_time, 6), "poses": poses,
             "pictures": pictures, "contacts": contacts}  # fmt: skip
    return batch, robot


def run_robot_trials(
    layout: Layout,
    method: MethodSpec,
    runs: int,
    episodes: int,
    seed: int = 0,
    *,
    recogniser=None,
    sink=None,
    robot_sink=None,
    settings: RobotSettings = RobotSettings(),
    progress: Callable[[int, int], None] | None = None,
) -> TrialResult:
    """``runs`` independent runs of ``episodes`` episodes of ``method`` with the robot."""
    if runs < 1 or episodes < 1:
        raise ValueError(f"runs={runs}, episodes={episodes}: both must be >= 1")
    shape = (runs, episodes)
    out = {k: np.zeros(shape, dt) for k, dt in (
        ("steps", np.int32), ("collisions", np.int32), ("returns", np.float32),
        ("reached_goal", bool), ("prevented", np.int32), ("greedy_optimal", bool),
        ("epsilon", np.float32))}  # fmt: skip
    placements = []
    for r in range(runs):
        env = SafeNavigation3DEnv(
            layout, method, recogniser, run=r, cell=settings.cell, timestep=settings.timestep,
            threshold=settings.threshold,
        )  # fmt: skip
        agent = TabularAgent(method, layout.n_cells, run_seeds(seed, r).agent)
        try:
            for ep in range(episodes):
                arrays, steps = _episode(env, agent, seed if ep == 0 else None)
                if ep == 0:
                    placements.append(env.world.placement)
                    if sink is not None and env._sees:
                        sink.substitution(run=r, episode=0, step=0, picture=-1, category=-1,
                                          position=-1, support_accuracy=env.recogniser.support_accuracy(r))  # fmt: skip
                batch, robot = _batch(r, ep, arrays, steps, agent, env)
                for k, key in (("steps", "steps"), ("collisions", "collisions"),
                               ("returns", "return_"), ("reached_goal", "reached_goal"),
                               ("prevented", "prevented"), ("greedy_optimal", "greedy_optimal"),
                               ("epsilon", "epsilon")):  # fmt: skip
                    out[k][r, ep] = (batch if k == "steps" else batch["summary"])[key][0]
                if sink is not None:
                    for pic in robot["pictures"]:
                        if pic["substituted"] >= 0:
                            sink.substitution(run=r, episode=ep, step=pic["step"], picture=-1,
                                              category=pic["true"], position=pic["substituted"],
                                              support_accuracy=env.recogniser.support_accuracy(r))  # fmt: skip
                    sink.episodes(**batch)
                if robot_sink is not None:
                    robot_sink.episode(**robot)
                if progress is not None:
                    progress(r, ep)
        finally:
            env.close()
    return TrialResult(layout, method, seed, placements=placements, **out)


def _named(scores: np.ndarray) -> int:
    """The category a live picture's scores name: the top one, or -1 when all are 0 (a model of
    recognition that did not recognise the picture, :class:`pipeline.robot.live.LiveByPicture`)."""
    return int(scores.argmax()) if scores.max() > 0 else -1
