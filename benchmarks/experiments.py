"""Wall time of every experiment of the paper at the paper's scale (100 runs x 500 episodes per
cell), with the Relation Network in the loop and every episode recorded to MCAP.

    python -m benchmarks.experiments [--out /tmp/bench-experiments] [--no-record]

Runs `python -m pipeline trials +experiment=<name>` for fig8, fig9, fig10 and table3 into a
scratch folder (replaced on every run; the committed datasets/runs are left alone) and prints each
experiment's wall time (process start to end, numba compile and model loading included), its agent
steps per second of wall time, and each cell's trial time.
Writes reports/benchmarks/experiments.json.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._output import write_figures

EXPERIMENTS = ("fig8", "fig9", "fig10", "table3")


def agent_steps(out: Path, cells: dict) -> int:
    """The agent steps of every run of every cell, from the cells' ``summary.json``."""
    return sum(
        r["steps"]
        for c in cells
        for r in json.loads((out / c / "summary.json").read_text())["runs"]
    )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", default="/tmp/bench-experiments")
    ap.add_argument(
        "--no-record", action="store_true", help="run without MCAP records (to see their cost)"
    )
    ap.add_argument("--json", default="reports/benchmarks/experiments.json")
    args = ap.parse_args()
    rows, total = [], 0.0
    for exp in EXPERIMENTS:
        shutil.rmtree(Path(args.out) / exp, ignore_errors=True)  # outside the timing
        t0 = time.perf_counter()
        cmd = [
            sys.executable,
            "-m",
            "pipeline",
            "trials",
            f"+experiment={exp}",
            "progress=false",
            f"out={args.out}/{exp}",
            "overwrite=true",
            f"record={'none' if args.no_record else 'steps'}",
            f"timing_file={args.out}/{exp}-timing.json",
        ]
        out = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if out.returncode != 0:
            sys.exit(f"{exp} failed:\n{out.stderr[-2000:]}")
        total += wall
        timing = json.loads((Path(args.out) / f"{exp}-timing.json").read_text())
        cells = {name: t["seconds"] for name, t in timing.items()}
        steps = agent_steps(Path(args.out) / exp, cells)
        rows.append(
            {
                "experiment": exp,
                "wall_seconds": round(wall, 2),
                "agent_steps": steps,
                "steps_per_second": round(steps / wall),
                "cells": cells,
                "kernel_seconds": round(sum(t["kernel_seconds"] for t in timing.values()), 2),
            }
        )
        print(
            f"{exp:<8} {wall:7.1f} s wall  {steps / wall / 1e6:5.2f} M agent steps/s   "
            + "  ".join(f"{n} {s:.1f}s" for n, s in rows[-1]["cells"].items())
        )
    print(f"total    {total:7.1f} s{'' if not args.no_record else ' without records'}")
    write_figures(
        args.json,
        {"record": not args.no_record, "total_seconds": round(total, 2), "experiments": rows},
        "benchmarks.experiments",
    )


if __name__ == "__main__":
    main()
