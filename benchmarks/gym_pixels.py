"""Camera robot in Gymnasium: steps per second with and without pixel observations (``obs_type``).

    python -m benchmarks.gym_pixels [--maze 5x5] [--runs 3] [--steps 2000]

Prints (and writes ``reports/benchmarks/gym_pixels.json``), for each ``obs_type`` of
``SafeNav3D-<maze>-v0`` (method ``shield``: no live pictures, so only the observation differs):

* **steps per second** over ``--runs`` runs of ``--steps`` steps, each action drawn at random
  among the allowed ones (seeded), the runs' ``reset(seed=...)`` included: a run renders each
  (cell, heading) it visits once, so the rate grows with the steps of a run;
* the **seconds of a new run** (``reset(seed=...)`` and its first step): the run's maze built in
  MuJoCo and, with pixels, its renderer;
* the **milliseconds of one picture**: the camera rendered from every cell and heading of a run's
  maze, the cost of a (cell, heading) the run had not seen;
* the 1-minute load average before and after: other work on the cores lowers every rate.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import pipeline  # noqa: E402, F401  (registers the ids)
from benchmarks._output import write_figures  # noqa: E402
from pipeline.robot.env import OBS_TYPES  # noqa: E402
from pipeline.robot.live_world import PICTURE_SIZE  # noqa: E402
from pipeline.robot.sim import RobotSim  # noqa: E402


def steps_per_second(maze: str, obs_type: str, runs: int, steps: int) -> dict:
    env = gym.make(f"SafeNav3D-{maze}-v0", obs_type=obs_type, max_episode_steps=-1)
    choose = np.random.default_rng(0)
    new_run, total = [], 0.0
    for seed in range(runs):
        t0 = time.perf_counter()
        _, info = env.reset(seed=seed)
        _, _, _, _, info = env.step(int(choose.choice(np.flatnonzero(info["action_mask"]))))
        new_run.append(time.perf_counter() - t0)
        for _ in range(steps - 1):
            action = int(choose.choice(np.flatnonzero(info["action_mask"])))
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                _, info = env.reset()
        total += time.perf_counter() - t0
    env.close()
    return {
        "obs_type": obs_type,
        "steps_per_second": round(runs * steps / total, 1),
        "new_run_seconds": round(float(np.median(new_run)), 3),
    }


def milliseconds_a_picture(maze: str) -> float:
    """The camera from every cell and heading of run 0's maze, rendered without the run's cache."""
    robot = gym.make(f"SafeNav3D-{maze}-v0").unwrapped
    sim = RobotSim(robot.layout, robot.world.placement)
    sim.place(robot.layout.start, 0)
    sim.picture(PICTURE_SIZE)  # the renderer is made on first use
    poses = [(cell, heading) for cell in range(robot.layout.n_cells) for heading in range(4)]
    t0 = time.perf_counter()
    for pose in poses:
        sim.place(*pose)
        sim.picture(PICTURE_SIZE)
    seconds = time.perf_counter() - t0
    sim.close()
    return round(1000 * seconds / len(poses), 2)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--maze", default="5x5", choices=["5x5", "7x7", "11x11"])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--out", default="reports/benchmarks/gym_pixels.json")
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    rows = [steps_per_second(args.maze, t, args.runs, args.steps) for t in OBS_TYPES]
    picture_ms = milliseconds_a_picture(args.maze)
    load_after = os.getloadavg()[0]
    print(
        f"SafeNav3D-{args.maze}-v0, {args.runs} runs x {args.steps} steps, random allowed actions"
    )
    print(f"{'obs_type':<14}{'steps/s':>10}{'new run s':>11}")
    for row in rows:
        print(
            f"{row['obs_type']:<14}{row['steps_per_second']:>10.1f}{row['new_run_seconds']:>11.3f}"
        )
    print(
        f"one picture ({PICTURE_SIZE} x {PICTURE_SIZE}), not yet rendered in the run: {picture_ms} ms"
    )
    print(f"load average (1 min) before / after: {load_before:.2f} / {load_after:.2f}")
    figures = {
        "maze": args.maze,
        "runs": args.runs,
        "steps": args.steps,
        "rows": rows,
        "picture_milliseconds": picture_ms,
        "load_average_before": round(load_before, 2),
        "load_average_after": round(load_after, 2),
    }
    write_figures(args.out, figures, "benchmarks.gym_pixels")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
