"""Recording overhead on the real experiment: the paper-scale 11x11 few-shot trial (fewshot_dss,
substitution way 1, 100 runs x 500 episodes) with the trained Relation Network in the loop, timed
without a sink and with the MCAP RecordWriter, alternating, several repeats.

    python -m benchmarks.records_overhead [--repeats 3]

Needs datasets/models/relation_net.pt and datasets/images (dvc repro). Prints every time, the
overhead of the fastest recorded run over the fastest unrecorded one and of the medians, and the
bytes per recorded step; writes reports/benchmarks/records_overhead.json.
"""
from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.records.writer import RecordWriter
from pipeline.rl.methods import get_method
from pipeline.rl.runner import run_trials
from pipeline.world.maze import load_layout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--checkpoint", default="datasets/models/relation_net.pt")
    ap.add_argument("--images-dir", default="datasets/images")
    ap.add_argument("--json", default="reports/benchmarks/records_overhead.json")
    args = ap.parse_args()
    layout, method = load_layout("11x11"), get_method("fewshot_dss")

    def recogniser():
        return RelationRecogniser.from_files(args.checkpoint, args.images_dir, substitution_way=1)

    run_trials(layout, method, 2, 2, progress=False, recogniser=recogniser())  # compile
    times = {"no_sink": [], "mcap": []}
    size = steps = 0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            for kind in times:
                rec = recogniser()
                path = Path(tmp) / f"r{i}.mcap"
                writer = RecordWriter(path, maze={"layout": list(layout.rows)}, flush_every=500) if kind == "mcap" else None
                t0 = time.perf_counter()
                result = run_trials(layout, method, 100, 500, progress=False, recogniser=rec, sink=writer)
                if writer is not None:
                    writer.close()
                times[kind].append(time.perf_counter() - t0)
                if writer is not None:
                    size, steps = path.stat().st_size, int(result.steps.sum())
    best = min(times["mcap"]) / min(times["no_sink"]) - 1
    med = statistics.median(times["mcap"]) / statistics.median(times["no_sink"]) - 1
    print(f"11x11 fewshot_dss, 100 x 500, {steps} steps, Relation Network in the loop")
    print(f"  without records: {', '.join(f'{t:.2f}' for t in times['no_sink'])} s")
    print(f"  with records:    {', '.join(f'{t:.2f}' for t in times['mcap'])} s")
    print(f"  overhead: {100 * best:.0f}% (fastest vs fastest), {100 * med:.0f}% (median vs median); goal <= 25%")
    print(f"  {size / steps:.3f} bytes per recorded step")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({"times": times, "overhead_best": best, "overhead_median": med,
                                           "bytes_per_step": size / steps, "steps": steps}, indent=2) + "\n")


if __name__ == "__main__":
    main()
