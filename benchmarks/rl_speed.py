"""Agent steps per second: the batched numba runner vs the Gymnasium loop, per method, on 11x11.

    python -m benchmarks.rl_speed [--runs 100] [--episodes 500] [--maze 11x11]

Prints a table and writes reports/benchmarks/rl_speed.json. The batched runner is timed on one
numba thread and on all threads (after a warm-up that compiles the kernels); the Gymnasium loop
steps the same rules one at a time through ``SafeNavigationEnv`` and ``TabularAgent``. The ratios
batched / Gymnasium loop compare figures measured in the same run, one method right after the
other (the host's speed varies between runs).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from benchmarks._output import write_figures
from pipeline.rl.agents import TabularAgent, run_episode
from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import get_method
from pipeline.rl.oracle import OracleRecogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import METHODS
from pipeline.rl.runner import run_trials
from pipeline.world.maze import load_layout


class HalfRight(OracleRecogniser):
    """Right on even picture ids, wrong on odd ones: exercises both branches of Algorithm 1."""

    def predictions(self, run):
        p = super().predictions(run)
        p[1::2] = (p[1::2] + 1) % 5
        return p


def time_batched(layout, method, runs, episodes, threads):
    numba.set_num_threads(threads)
    rec = HalfRight() if method.uses_recogniser else None
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        res = run_trials(
            layout,
            method,
            runs,
            episodes,
            seed=0,
            recogniser=rec,
            progress=False,
            chunk_episodes=episodes,
        )
        best = min(best, time.perf_counter() - t0)
    return int(res.steps.sum()), best


def time_gym(layout, method, episodes, budget_s=3.0):
    rec = HalfRight() if method.uses_recogniser else None
    env = SafeNavigationEnv(layout, method, recogniser=rec)
    agent = TabularAgent(method, layout.n_cells, run_seeds(0, 0).agent)
    steps, t0 = 0, time.perf_counter()
    for ep in range(episodes):
        steps += len(run_episode(env, agent, seed=0 if ep == 0 else None)["states"])
        if time.perf_counter() - t0 > budget_s:
            break
    return steps, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--maze", default="11x11")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--episodes", type=int, default=500)
    ap.add_argument("--out", default="reports/benchmarks/rl_speed.json")
    args = ap.parse_args()
    layout = load_layout(args.maze)
    all_threads = numba.config.NUMBA_NUM_THREADS
    run_trials(layout, get_method("sarsa"), 2, 2, progress=False)  # compile
    rows = []
    print(
        f"maze {args.maze}, {args.runs} runs x {args.episodes} episodes; numba threads: 1 and {all_threads}"
    )
    print(
        f"{'method':<13}{'steps':>11}{'1 thread M/s':>14}{f'{all_threads} threads M/s':>15}{'gym k/s':>10}"
        f"{'x gym (1 thr)':>15}{f'x gym ({all_threads} thr)':>15}"
    )
    for name in [m.name for m in METHODS]:
        method = get_method(name)
        steps, t1 = time_batched(layout, method, args.runs, args.episodes, 1)
        _, tn = time_batched(layout, method, args.runs, args.episodes, all_threads)
        gsteps, gt = time_gym(layout, method, args.episodes)
        row = {
            "method": name,
            "steps": steps,
            "batched_1thread_steps_per_s": steps / t1,
            f"batched_{all_threads}threads_steps_per_s": steps / tn,
            "gym_steps_per_s": gsteps / gt,
            "speedup_1thread_vs_gym": (steps / t1) / (gsteps / gt),
            f"speedup_{all_threads}threads_vs_gym": (steps / tn) / (gsteps / gt),
        }
        rows.append(row)
        print(
            f"{name:<13}{steps:>11}{steps / t1 / 1e6:>14.2f}{steps / tn / 1e6:>15.2f}"
            f"{gsteps / gt / 1e3:>10.1f}{row['speedup_1thread_vs_gym']:>15.0f}"
            f"{row[f'speedup_{all_threads}threads_vs_gym']:>15.0f}"
        )
    numba.set_num_threads(all_threads)
    write_figures(
        args.out,
        {"maze": args.maze, "runs": args.runs, "episodes": args.episodes, "rows": rows},
        "benchmarks.rl_speed",
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
