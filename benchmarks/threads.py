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
import os
from pathlib import Path

from benchmarks._in_process import differing, timed_run, warm_up
from benchmarks._output import write_figures
from pipeline import threads
from pipeline.fewshot import score_cache


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
    warm_up(args.experiment, out)
    best: dict[int, float] = {}
    try:
        for _ in range(args.repeats):
            for n in (budget, 2):
                threads.TORCH_THREADS_BESIDE_NUMBA = n
                seconds = timed_run(
                    args.experiment, out / "run", out / f"torch{n}", score_cache.disabled()
                )
                best[n] = min(best.get(n, seconds), seconds)
    finally:
        threads.TORCH_THREADS_BESIDE_NUMBA = budget
    summaries, differ = differing(out / f"torch{budget}", out / "torch2", ("summary.json",))
    figures = {
        "experiment": args.experiment,
        "repeats": args.repeats,
        "cores": os.cpu_count(),
        "numba_threads": threads.trials_budget(0, 1).numba,
        f"wall_seconds_torch_{budget}_thread": round(best[budget], 2),
        "wall_seconds_torch_2_threads": round(best[2], 2),
        "summaries_compared": summaries,
        "summaries_that_differ": differ,
        "load_average_after": os.getloadavg()[0],
    }
    print(
        f"{args.experiment}, every column recomputed: torch on {budget} thread {best[budget]:.1f} s, "
        f"on 2 threads {best[2]:.1f} s (best of {args.repeats}, numba on "
        f"{figures['numba_threads']}); {summaries} summaries "
        + ("the same bytes" if not differ else f"DIFFER: {differ}")
    )
    write_figures(args.json, figures, "benchmarks.threads")


if __name__ == "__main__":
    main()
