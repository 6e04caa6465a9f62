"""The thread budget: an experiment with torch on one thread beside numba (pipeline/threads.py) and
on two, every score column recomputed (no shared store), so torch's share is what differs.

    python -m benchmarks.threads [--experiment fig9] [--repeats 2] [--out /tmp/bench-threads]

Runs the trials stage in this process at the paper's scale with records written, torch's threads
set by patching ``pipeline.threads.TORCH_THREADS_BESIDE_NUMBA`` (1: the budget, 2: what torch
takes by default on this machine), interleaved, after a smoke-scale warm-up. Prints the best wall
time of each and whether every cell's ``summary.json`` is the same bytes. Writes
reports/benchmarks/threads.json.
"""

from __future__ import annotations

import argparse
import contextlib
import filecmp
import os
import shutil
import time
from pathlib import Path

from benchmarks._output import write_figures
from pipeline import threads
from pipeline.fewshot import score_cache
from pipeline.stages._common import run_stage


def run_once(experiment: str, out: Path, kept: Path, torch_threads: int) -> float:
    """Wall seconds of ``experiment`` with ``torch_threads`` torch threads beside numba."""
    shutil.rmtree(out, ignore_errors=True)
    shutil.rmtree(kept, ignore_errors=True)
    threads.TORCH_THREADS_BESIDE_NUMBA = torch_threads
    t0 = time.perf_counter()
    with score_cache.disabled(), contextlib.redirect_stdout(open(os.devnull, "w")):
        run_stage("trials", [f"+experiment={experiment}", "progress=false", f"out={out}"])
    seconds = time.perf_counter() - t0
    out.rename(kept)
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--experiment", default="fig9")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default="/tmp/bench-threads")
    ap.add_argument("--json", default="reports/benchmarks/threads.json")
    args = ap.parse_args()
    out, budget = Path(args.out), threads.TORCH_THREADS_BESIDE_NUMBA
    with contextlib.redirect_stdout(open(os.devnull, "w")):
        run_stage(
            "trials",
            [f"+experiment={args.experiment}", "profile=smoke", "progress=false", "overwrite=true"]
            + [f"out={out / 'warm-up'}"],
        )
    best: dict[int, float] = {}
    try:
        for _ in range(args.repeats):
            for n in (budget, 2):
                seconds = run_once(args.experiment, out / "run", out / f"torch{n}", n)
                best[n] = min(best.get(n, seconds), seconds)
    finally:
        threads.TORCH_THREADS_BESIDE_NUMBA = budget
    summaries = sorted(
        p.relative_to(out / "torch2") for p in (out / "torch2").rglob("summary.json")
    )
    differ = [
        str(p)
        for p in summaries
        if not filecmp.cmp(out / f"torch{budget}" / p, out / "torch2" / p, shallow=False)
    ]
    figures = {
        "experiment": args.experiment,
        "repeats": args.repeats,
        "cores": os.cpu_count(),
        "numba_threads": threads.trials_budget(0, 1).numba,
        f"wall_seconds_torch_{budget}_thread": round(best[budget], 2),
        "wall_seconds_torch_2_threads": round(best[2], 2),
        "summaries_compared": len(summaries),
        "summaries_that_differ": differ,
        "load_average_after": os.getloadavg()[0],
    }
    print(
        f"{args.experiment}, every column recomputed: torch on {budget} thread {best[budget]:.1f} s, "
        f"on 2 threads {best[2]:.1f} s (best of {args.repeats}, numba on "
        f"{figures['numba_threads']}); {len(summaries)} summaries "
        + ("the same bytes" if not differ else f"DIFFER: {differ}")
    )
    write_figures(args.json, figures, "benchmarks.threads")


if __name__ == "__main__":
    main()
