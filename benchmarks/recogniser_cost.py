"""What the Relation Network costs an experiment: Table 3 at paper scale with it, its score columns
kept from a run before (warm) and kept from none (cold), against the same experiment with
``recogniser=oracle`` (the recogniser's cost gone).

    python -m benchmarks.recogniser_cost [--experiment table3] [--repeats 3] [--out /tmp/bench-recogniser-cost]

Each repeat runs the three, whole processes (start-up, torch and the checkpoint included), in an
order that rotates from repeat to repeat: ``trials +experiment=<name>`` with the default recogniser
and ``FSRL_SCORE_CACHE`` naming a folder a warm-up run filled (warm), the same with a new empty
folder (cold), and with ``recogniser=oracle``. The goal (issue 40): warm and cold within
:data:`GOAL` of the oracle. The ratios are paired (each repeat's runs back to back; a slow spell of
the shared machine cancels), their median quoted. The records of the warm and cold runs are
compared byte for byte (``same_bytes``): kept columns must not change a bit. Writes
reports/benchmarks/recogniser_cost.json.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._output import write_figures

#: The recogniser's run over the oracle's that the experiment may take (issue 40).
GOAL = 1.3
VARIANTS = ("warm", "cold", "oracle")


def run(experiment: str, out: Path, cache: Path | None, oracle: bool) -> float:
    """Wall seconds of one whole ``trials`` process into ``out`` (replaced). Every run writes to
    the same ``out``: the records keep the config, ``out`` included."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "pipeline", "trials", f"+experiment={experiment}"]
    cmd += ["progress=false", f"out={out}", "overwrite=true"]
    cmd += ["recogniser=oracle"] if oracle else []
    env = os.environ | {"FSRL_SCORE_CACHE": str(cache) if cache else "off"}
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    return wall


def same_tree(a: Path, b: Path) -> bool:
    """Every file under ``a`` and ``b`` the same bytes (the folder's lock file aside)."""
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.name != ".owner")
    theirs = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file() and p.name != ".owner")
    return files == theirs and all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--experiment", default="table3")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default="/tmp/bench-recogniser-cost")
    ap.add_argument("--json", default="reports/benchmarks/recogniser_cost.json")
    args = ap.parse_args()
    scratch = Path(args.out)
    shutil.rmtree(scratch, ignore_errors=True)
    warm_cache, out = scratch / "warm-cache", scratch / "out"
    run(args.experiment, out, warm_cache, oracle=False)  # fills the warm folder
    walls: dict[str, list[float]] = {v: [] for v in VARIANTS}
    for i in range(args.repeats):
        for variant in VARIANTS[i % 3 :] + VARIANTS[: i % 3]:
            cache = {"warm": warm_cache, "cold": scratch / f"cold-cache-{i}"}.get(variant)
            walls[variant].append(run(args.experiment, out, cache, oracle=variant == "oracle"))
            shutil.rmtree(scratch / variant, ignore_errors=True)
            out.rename(scratch / variant)  # the last repeat's records, kept to compare
            print(f"repeat {i + 1}: {variant:<6} {walls[variant][-1]:6.1f} s", flush=True)
    ratios = {
        v: statistics.median(a / b for a, b in zip(walls[v], walls["oracle"]))
        for v in ("warm", "cold")
    }
    same = same_tree(scratch / "warm", scratch / "cold")
    for v in ("warm", "cold"):
        met = "met" if ratios[v] <= GOAL else "NOT met"
        print(
            f"{v}: median {statistics.median(walls[v]):.1f} s, {ratios[v]:.2f}x the oracle's "
            f"median {statistics.median(walls['oracle']):.1f} s (goal <= {GOAL}: {met})"
        )
    print(f"records of the warm and cold runs the same bytes: {same}")
    write_figures(
        args.json,
        {
            "experiment": args.experiment,
            "repeats": args.repeats,
            "goal_over_oracle": GOAL,
            "wall_seconds": {v: [round(w, 2) for w in ws] for v, ws in walls.items()},
            "median_wall_seconds": {v: round(statistics.median(ws), 2) for v, ws in walls.items()},
            "paired_ratio_over_oracle": {v: round(r, 3) for v, r in ratios.items()},
            "same_bytes_warm_and_cold": same,
            "load_average_after": os.getloadavg()[0],
        },
        "benchmarks.recogniser_cost",
    )
    if not same:
        sys.exit("the warm and cold runs recorded different bytes")


if __name__ == "__main__":
    main()
