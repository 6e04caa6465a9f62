"""Robot benchmark: ``python -m benchmarks.robot3d [--profile paper|smoke]`` (``make bench``).

Prints (and writes ``reports/benchmarks/robot3d.json``) what the camera robot costs (docs/robot3d.md
"Cost"):

* **the robot stage**: the ``robot3d`` experiment (``trials +experiment=robot3d``, at the profile's
  scale: 100 runs x 500 episodes with ``paper``) run as DVC runs it, in a child process, into a
  temporary folder: its wall time, CPU time, and each cell's trial seconds by world;
* the motion table: seconds to simulate every turn and drive once (``robot.motion``);
* live pictures per second: one run's pictures of the 7x7 maze rendered in MuJoCo (the robot
  stage's main cost), and the range sensor's check that comes with them;
* the 1-minute load average before and after: other work on the 2 cores lowers every rate.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from benchmarks._output import write_figures  # noqa: E402


def robot_stage(profile: str) -> dict:
    """The ``robot3d`` experiment in a child process, as ``dvc repro`` runs it."""
    with tempfile.TemporaryDirectory(prefix="robot3d-bench-") as tmp:
        timing = Path(tmp) / "timing.json"
        stage = ["trials", "+experiment=robot3d", f"profile={profile}", "progress=false"]
        cmd = [sys.executable, "-m", "pipeline", *stage, f"out={tmp}/out", f"timing_file={timing}"]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cells = {name: t["seconds"] for name, t in json.loads(timing.read_text()).items()}
    by_world = {"robot3d": 0.0, "grid": 0.0}
    for name, seconds in cells.items():
        by_world["robot3d" if "_robot3d" in name else "grid"] += seconds
    return {
        "profile": profile,
        "wall_seconds": round(wall, 1),
        "cpu_seconds": round(
            (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), 1
        ),
        "cells": len(cells),
        "trial_seconds_by_world": {k: round(v, 1) for k, v in by_world.items()},
        "slowest_cells": dict(sorted(cells.items(), key=lambda kv: -kv[1])[:4]),
    }


def motion_table_seconds() -> float:
    from pipeline.robot.motion import motion_table

    t0 = time.perf_counter()
    motion_table(1.0, 0.02)
    return round(time.perf_counter() - t0, 2)


def live_pictures(maze: str = "7x7") -> dict:
    from pipeline.robot.live_world import RobotSettings, rendered_run
    from pipeline.world.maze import load_layout

    layout = load_layout(maze)
    t0 = time.perf_counter()
    got = rendered_run(layout.rows, 0, 0, RobotSettings())
    seconds = time.perf_counter() - t0
    return {
        "maze": maze,
        "pictures_a_run": len(got.pairs),
        "seconds_a_run": round(seconds, 2),
        "pictures_per_s": round(len(got.pairs) / seconds, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="paper", choices=["paper", "smoke"])
    parser.add_argument("--out", default="reports/benchmarks/robot3d.json")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    figures = {
        "machine": {
            "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
        },
        "motion_table_seconds": motion_table_seconds(),
        "live_pictures": live_pictures(),
        "robot_stage": robot_stage(args.profile),
        "load_1min": {"before": round(load_before, 2), "after": round(os.getloadavg()[0], 2)},
    }
    path = write_figures(args.out, figures, "benchmarks.robot3d")
    stage = figures["robot_stage"]
    print(
        f"robot stage ({stage['profile']} profile, {stage['cells']} cells): "
        f"{stage['wall_seconds']:.0f} s wall, {stage['cpu_seconds']:.0f} s CPU; trials by world "
        f"{stage['trial_seconds_by_world']}; live pictures "
        f"{figures['live_pictures']['pictures_per_s']}/s; motion table "
        f"{figures['motion_table_seconds']} s; load {figures['load_1min']} -> {path}"
    )


if __name__ == "__main__":
    main()
