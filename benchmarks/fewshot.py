"""Speed of the few-shot module (docs/fewshot.md; goals in README "Measured"), on this machine:

1. meta-training with the default ``conf/meta_train.yaml``: time until a model-selection
   evaluation first reaches the validation goal (75%), total wall time, and the 600-episode
   accuracy;
2. classifying one picture against a support set right after a substitution (goal < 5 ms);
3. the whole accuracy study of ``conf/accuracy.yaml`` (goal < 3 minutes);
4. what one training episode (5-way 5-shot, 5 queries per class, the default
   ``conf/meta_train.yaml`` otherwise) costs at each ``--input-sizes`` (48, the default,
   and 84, the paper's): the training loop of :func:`pipeline.fewshot.training.meta_train` over
   ``--cost-episodes`` episodes of the rendered training classes, divided by their number (one tiny
   evaluation at the end included), after a three-episode warm-up run.

    python -m benchmarks.fewshot [--images-dir DIR] [--skip-train --checkpoint FILE] [--only-episode-cost]

Prints the figures and writes ``reports/benchmarks/fewshot.json``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from benchmarks._output import write_figures
from pipeline.config.compose import load_config
from pipeline.fewshot.accuracy_study import run_study
from pipeline.fewshot.data import PictureSet, load_split
from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.fewshot.training import TrainConfig, meta_train
from pipeline.stages import run_stage


def bench_training(images_dir: str, out: Path) -> dict:
    ckpt = out / "relation_net.pt"
    overrides = [
        f"images_dir={images_dir}",
        f"checkpoint={ckpt}",
        f"metrics_file={out}/metrics.json",
        f"history_file={out}/train_history.csv",
    ]
    start = time.perf_counter()
    metrics = run_stage("meta_train", overrides)
    wall = time.perf_counter() - start
    return {
        "checkpoint": str(ckpt),
        "wall_s": wall,
        **{
            k: metrics[k]
            for k in (
                "test_accuracy",
                "test_ci95",
                "val_accuracy",
                "val_ci95",
                "time_to_target_s",
                "train_seconds",
                "eval_seconds",
                "episodes_trained",
                "selected_episode",
            )
        },
    }


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
    return {
        "study_s": time.perf_counter() - start,
        "repeats": cfg.study.repeats,
        "baseline_accuracy": result.baseline_accuracy,
        "table2": {str(k): v for k, v in result.table2.items()},
    }


def bench_episode_cost(images_dir: str, sizes: list[int], episodes: int) -> dict:
    """Seconds per training episode at each input size (:func:`meta_train` with one evaluation, on
    five validation classes of ten pictures, at the end)."""
    out = {}
    for size in sizes:
        train = load_split(images_dir, "train", size)
        val = load_split(images_dir, "val", size)
        keep = np.concatenate([np.flatnonzero(val.labels == c)[:10] for c in range(5)])
        val = PictureSet(
            val.images[keep],
            val.labels[keep],
            val.picture_ids[keep],
            val.class_names[:5],
            tuple(val.files[i] for i in keep),
        )
        config = TrainConfig(
            input_size=size,
            episodes=episodes,
            val_every=episodes,
            val_episodes=1,
            eval_episodes=2,
            eval_queries=5,
            max_minutes=60.0,
        )
        meta_train(
            train, val, replace(config, episodes=3, val_every=3), progress=False
        )  # warm-up: kernels chosen
        result = meta_train(train, val, config, progress=False)
        out[str(size)] = {
            "seconds_per_episode": result.metrics["train_seconds"] / episodes,
            "episodes": episodes,
        }
        print(
            f"input {size} px: {out[str(size)]['seconds_per_episode']:.3f} s per training episode "
            f"({episodes} episodes, {torch.get_num_threads()} threads)"
        )
    return out


def bench_the_rest(args: argparse.Namespace, out: Path) -> dict:
    """Items 1-3: training (unless ``--skip-train``), the recogniser and the accuracy study."""
    figures = {}
    checkpoint = args.checkpoint
    if not args.skip_train:
        figures["meta_train"] = t = bench_training(args.images_dir, out)
        checkpoint = t["checkpoint"]
        print(
            f"meta-training: {t['test_accuracy']:.4f} +- {t['test_ci95']:.4f} test accuracy "
            f"({t['val_accuracy']:.4f} +- {t['val_ci95']:.4f} validation); goal reached after "
            f"{t['time_to_target_s']} s; {t['episodes_trained']} episodes; wall {t['wall_s']:.0f} s (goal <= 900 s)"
        )
    figures["recogniser"] = r = bench_recogniser(checkpoint, args.images_dir)
    print(
        f"classify one picture after a substitution: median {r['classify_after_change_ms_median']:.2f} ms, "
        f"p99 {r['classify_after_change_ms_p99']:.2f} ms (goal < 5 ms); cached {r['classify_cached_ms_median']:.3f} ms"
    )
    figures["accuracy_study"] = a = bench_study(checkpoint, args.images_dir)
    print(f"accuracy study ({a['repeats']} repeats): {a['study_s']:.1f} s (goal < 180 s)")
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--images-dir", default="datasets/images")
    parser.add_argument(
        "--skip-train", action="store_true", help="benchmark only the recogniser and the study"
    )
    parser.add_argument(
        "--checkpoint", default="datasets/models/relation_net.pt", help="with --skip-train"
    )
    parser.add_argument(
        "--out-dir",
        default=None,
        help="keep the trained checkpoint, metrics and history here (default: a temporary folder)",
    )
    parser.add_argument("--input-sizes", type=int, nargs="+", default=[48, 84])
    parser.add_argument(
        "--cost-episodes", type=int, default=30, help="training episodes timed per input size"
    )
    parser.add_argument("--only-episode-cost", action="store_true", help="measure only item 4")
    parser.add_argument("--json", default="reports/benchmarks/fewshot.json")
    args = parser.parse_args()
    torch.set_num_threads(2)
    figures: dict = {"torch_threads": torch.get_num_threads(), "images_dir": args.images_dir}
    figures["episode_cost"] = bench_episode_cost(
        args.images_dir, args.input_sizes, args.cost_episodes
    )
    if not args.only_episode_cost:
        with tempfile.TemporaryDirectory() as tmp:
            figures.update(bench_the_rest(args, Path(args.out_dir or tmp)))
    path = write_figures(args.json, figures, "benchmarks.fewshot")
    print(f"written {path}")


if __name__ == "__main__":
    main()
