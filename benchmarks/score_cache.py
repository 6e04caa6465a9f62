"""Relation scores computed once: one experiment run with and without the shared score store.

    python -m benchmarks.score_cache [--experiment table3] [--repeats 2] [--out /tmp/bench-score-cache]

Runs the trials stage in this process (``pipeline.stages.run_stage``) at the paper's
scale, records written, first with sharing turned off (``pipeline.fewshot.score_cache.disabled``:
each run recomputes a column after its own substitutions, as before the store) and then with it,
``--repeats`` times each, interleaved, after a smoke-scale warm-up (numba's cache, torch's import).
Prints the best wall time of each, the score columns computed and looked up, and whether every
``records.mcap`` and ``summary.json`` of the two is the same bytes (``filecmp`` with
``shallow=False``). Writes reports/benchmarks/score_cache.json.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from pathlib import Path

from benchmarks._in_process import differing, timed_run, warm_up
from benchmarks._output import write_figures
from pipeline.fewshot import score_cache


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--experiment", default="table3")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default="/tmp/bench-score-cache")
    ap.add_argument("--json", default="reports/benchmarks/score_cache.json")
    args = ap.parse_args()
    out = Path(args.out)
    warm_up(args.experiment, out)
    best: dict[str, float] = {}
    stats: dict[str, dict] = {}
    for _ in range(args.repeats):
        for label, share in (("without", False), ("with", True)):
            score_cache.clear()
            setting = contextlib.nullcontext() if share else score_cache.disabled()
            seconds = timed_run(args.experiment, out / "run", out / label, setting)
            best[label] = min(best.get(label, seconds), seconds)
            stats[label] = score_cache.statistics()
    compared, differ = differing(out / "without", out / "with", ("records.mcap", "summary.json"))
    figures = {
        "experiment": args.experiment,
        "repeats": args.repeats,
        "cores": os.cpu_count(),
        "wall_seconds_without_sharing": round(best["without"], 2),
        "wall_seconds_with_sharing": round(best["with"], 2),
        "columns_computed_without": stats["without"]["misses"],
        "columns_computed_with": stats["with"]["misses"],
        "column_lookups": stats["with"]["hits"] + stats["with"]["misses"],
        "files_compared": compared,
        "files_that_differ": differ,
        "load_average_after": os.getloadavg()[0],
    }
    print(
        f"{args.experiment}: {best['without']:.1f} s without sharing, {best['with']:.1f} s with "
        f"(best of {args.repeats}); columns computed {stats['without']['misses']:,} -> "
        f"{stats['with']['misses']:,} of {figures['column_lookups']:,} lookups; "
        f"{compared} records and summaries compared, "
        + ("all the same bytes" if not differ else f"{len(differ)} DIFFER: {differ[:5]}")
    )
    write_figures(args.json, figures, "benchmarks.score_cache")
    if differ:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
