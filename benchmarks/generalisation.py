"""Wall time of the generalisation experiment (100 layouts x 3 sizes x 7 methods x 20 runs x 500
episodes, Relation Network in the loop, every episode recorded) on this machine.

    python -m benchmarks.generalisation [--layouts 100] [--workers 2] [--out /tmp/bench-generalisation]

Runs `python -m pipeline trials +experiment=generalisation` into a scratch folder (deleted before
every run, outside the timing; datasets/runs is left alone) and prints the wall time (process
start to end: model loading, worker start-up and numba's cache included), the cells, the agent
steps and steps per second, the sum of the cells' trial times (what a cluster would share out) and, from
the same run, the kernel's time (inside ``kernel.advance_batch``, summed over the cells, shared by
the workers) beside the wall time: what set-up, recording and workers add to the kernel's work.
Then the same study again with ``record=none``, side by side: what its records cost of the wall
time, and how close the study comes to its goal without them. ``--layouts N`` runs N layouts
per size instead of 100; the figures for 100 are then extrapolated from the per-cell times and
labelled as such: the cells' trial times scaled, the rest of the wall time counted once.
Writes reports/benchmarks/generalisation.json.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._output import write_figures

PAPER_LAYOUTS = 100
#: The study's wall time over its kernel time: what set-up, recording and workers may add.
GOAL_WALL_OVER_KERNEL = 1.3


def extrapolate(wall: float, trial_seconds: float, workers: int, scale: float) -> float:
    """Wall time at ``scale`` times the cells: the cells' trial time (shared by the workers)
    scaled, the rest of the wall time (start-up, planning, workers starting) counted once."""
    cells_wall = trial_seconds / max(1, workers)
    return max(0.0, wall - cells_wall) + cells_wall * scale


def run_study(args: argparse.Namespace, *overrides: str) -> dict:
    """Run the study once (``overrides`` after the benchmark's own) into a fresh ``args.out``:
    its wall time, kernel time a worker, cells' trial times and agent steps."""
    timing = Path(args.out + "-timing.json")
    cmd = [
        sys.executable,
        "-m",
        "pipeline",
        "trials",
        "+experiment=generalisation",
        "progress=false",
        f"out={args.out}",
        "overwrite=true",
        f"workers={args.workers}",
        f"timing_file={timing}",
        f"profile.trials.layouts={args.layouts}",
        *overrides,
    ]
    shutil.rmtree(args.out, ignore_errors=True)  # the last run's cells: not part of the timing
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        sys.exit(f"generalisation {' '.join(overrides)} failed:\n{out.stderr[-2000:]}")
    timing_by_cell = json.loads(timing.read_text())
    cells = {name: t["seconds"] for name, t in timing_by_cell.items()}
    steps = sum(
        sum(
            r["steps"]
            for r in json.loads((Path(args.out) / c / "summary.json").read_text())["runs"]
        )
        for c in cells
    )
    return {
        "wall": wall,
        "kernel": sum(t["kernel_seconds"] for t in timing_by_cell.values()) / args.workers,
        "cells": cells,
        "steps": steps,
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--layouts", type=int, default=PAPER_LAYOUTS, help="layouts per size (paper scale: 100)"
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="/tmp/bench-generalisation")
    ap.add_argument("--json", default="reports/benchmarks/generalisation.json")
    args = ap.parse_args()
    study = run_study(args)
    bare = run_study(args, "record=none")
    wall, kernel, cells, steps = study["wall"], study["kernel"], study["cells"], study["steps"]
    trial_seconds = sum(cells.values())
    scale = PAPER_LAYOUTS / args.layouts
    result = {
        "layouts_per_size": args.layouts,
        "workers": args.workers,
        "cores": os.cpu_count(),
        "cells": len(cells),
        "wall_seconds": round(wall, 1),
        "agent_steps": steps,
        "steps_per_second": round(steps / wall),
        "kernel_seconds_a_worker": round(kernel, 1),
        "wall_over_kernel": round(wall / kernel, 2),
        "goal_wall_over_kernel": GOAL_WALL_OVER_KERNEL,
        "sum_of_cell_trial_seconds": round(trial_seconds, 1),
        "mean_cell_seconds": round(trial_seconds / len(cells), 3),
        "slowest_cell_seconds": round(max(cells.values()), 2),
        "record_none": {
            "wall_seconds": round(bare["wall"], 1),
            "kernel_seconds_a_worker": round(bare["kernel"], 1),
            "wall_over_kernel": round(bare["wall"] / bare["kernel"], 2),
        },
        "load_average_after": os.getloadavg()[0],
    }
    print(
        f"{len(cells)} cells ({args.layouts} layouts per size), {args.workers} workers: {wall:.1f} s wall, "
        f"{steps:,} agent steps, {steps / wall:,.0f} steps/s; cells' trials {trial_seconds:.1f} s in all "
        f"(mean {trial_seconds / len(cells):.3f} s, slowest {max(cells.values()):.2f} s)"
    )
    met = "met" if wall / kernel <= GOAL_WALL_OVER_KERNEL else "NOT met"
    print(
        f"the kernel: {kernel:.1f} s a worker (its time summed over the cells / {args.workers} "
        f"workers); wall / kernel = {wall / kernel:.2f} (goal <= {GOAL_WALL_OVER_KERNEL}: {met})"
    )
    print(
        f"the same study with record=none: {bare['wall']:.1f} s wall, the kernel "
        f"{bare['kernel']:.1f} s a worker, wall / kernel = {bare['wall'] / bare['kernel']:.2f}; "
        f"its records cost {wall - bare['wall']:.1f} s of the wall time"
    )
    if scale != 1:
        estimate = extrapolate(wall, trial_seconds, args.workers, scale)
        result["extrapolated_to_100_layouts_seconds"] = round(estimate, 1)
        print(
            f"EXTRAPOLATED to {PAPER_LAYOUTS} layouts per size (x{scale:g} the cells): about "
            f"{estimate:.0f} s wall (the cells' time scaled, the rest counted once)"
        )
    write_figures(args.json, result, "benchmarks.generalisation")


if __name__ == "__main__":
    main()
