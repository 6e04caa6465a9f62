"""Speed of the few-shot module (docs/fewshot.md; goals in README "Measured"), on this machine:

1. meta-training with the default ``conf/meta_train.yaml``: time until a model-selection evaluation
   first reaches the validation goal (75%), total wall time, and the 600-episode accuracy;
2. classifying one picture against a support set right after a substitution (goal < 5 ms);
3. the whole accuracy study of ``conf/accuracy.yaml`` (goal < 3 minutes).

    python -m benchmarks.fewshot [--images-dir DIR] [--skip-train --checkpoint FILE]

Prints the figures and writes ``reports/benchmarks/fewshot.json``.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from pipeline.fewshot.accuracy_study import run_study
from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.stages._common import load_config, run_stage


def bench_training(images_dir: str, out: Path) -> dict:
    ckpt = out / "relation_net.pt"
    overrides = [f"images_dir={images_dir}", f"checkpoint={ckpt}", f"metrics_file={out}/metrics.json", f"history_file={out}/train_history.csv"]
    start = time.perf_counter()
    metrics = run_stage("meta_train", overrides)
    wall = time.perf_counter() - start
    return {"checkpoint": str(ckpt), "wall_s": wall, **{k: metrics[k] for k in ("val_accuracy", "val_ci95", "time_to_target_s", "train_seconds", "eval_seconds", "episodes_trained", "selected_episode")}}


def bench_recogniser(checkpoint: str, images_dir: str, n: int = 2000) -> dict:
    rec = RelationRecogniser.from_files(checkpoint, images_dir, substitution_way=2)
    rec.start_run(0, seed=0)
    rng = np.random.default_rng(0)
    cats = rec.query_categories
    after_change, lookup = [], []
    for _ in range(n):
        pid = int(rng.integers(rec.n_pictures))
        probe = np.array([int(rng.integers(rec.n_pictures))])
        t0 = time.perf_counter()
        rec.learn_from_collision(0, pid, int(cats[pid]))
        rec.scores(0, probe)
        t1 = time.perf_counter()
        rec.scores(0, probe)
        t2 = time.perf_counter()
        after_change.append(t1 - t0)
        lookup.append(t2 - t1)
    ms = lambda xs, q: 1000 * float(np.quantile(xs, q))  # noqa: E731
    return {
        "classify_after_change_ms_median": ms(after_change, 0.5),
        "classify_after_change_ms_p99": ms(after_change, 0.99),
        "classify_cached_ms_median": ms(lookup, 0.5),
        "changes": n,
    }


def bench_study(checkpoint: str, images_dir: str) -> dict:
    cfg = load_config("accuracy")
    start = time.perf_counter()
    rec = RelationRecogniser.from_files(checkpoint, images_dir, substitution_way=0)
    result = run_study(rec, rec.query_categories, cfg.study)
    return {"study_s": time.perf_counter() - start, "repeats": cfg.study.repeats, "baseline_accuracy": result.baseline_accuracy, "table2": {str(k): v for k, v in result.table2.items()}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--images-dir", default="datasets/images")
    parser.add_argument("--skip-train", action="store_true", help="benchmark only the recogniser and the study")
    parser.add_argument("--checkpoint", default="datasets/models/relation_net.pt", help="with --skip-train")
    parser.add_argument("--out-dir", default=None, help="keep the trained checkpoint, metrics and history here (default: a temporary folder)")
    parser.add_argument("--json", default="reports/benchmarks/fewshot.json")
    args = parser.parse_args()
    torch.set_num_threads(2)
    figures: dict = {"torch_threads": torch.get_num_threads(), "images_dir": args.images_dir}
    with tempfile.TemporaryDirectory() as tmp:
        checkpoint = args.checkpoint
        if not args.skip_train:
            figures["meta_train"] = bench_training(args.images_dir, Path(args.out_dir or tmp))
            checkpoint = figures["meta_train"]["checkpoint"]
            t = figures["meta_train"]
            print(f"meta-training: {t['val_accuracy']:.4f} +- {t['val_ci95']:.4f} val accuracy; goal reached after "
                  f"{t['time_to_target_s']} s; {t['episodes_trained']} episodes; wall {t['wall_s']:.0f} s (goal <= 900 s)")
        figures["recogniser"] = bench_recogniser(checkpoint, args.images_dir)
        r = figures["recogniser"]
        print(f"classify one picture after a substitution: median {r['classify_after_change_ms_median']:.2f} ms, "
              f"p99 {r['classify_after_change_ms_p99']:.2f} ms (goal < 5 ms); cached {r['classify_cached_ms_median']:.3f} ms")
        figures["accuracy_study"] = bench_study(checkpoint, args.images_dir)
        print(f"accuracy study ({figures['accuracy_study']['repeats']} repeats): {figures['accuracy_study']['study_s']:.1f} s (goal < 180 s)")
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(figures, indent=2) + "\n")
    print(f"written {path}")


if __name__ == "__main__":
    main()
