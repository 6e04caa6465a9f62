"""Stage ``meta_train``: episodic meta-training of the Relation Network, checkpoint chosen on held-out classes.

Episodic meta-training on the rendered training classes, checkpoint selection on the validation
classes (paper section 3.2.1; docs/fewshot.md).

    python -m pipeline meta_train [images_dir=...] [train.episodes=...]

Writes ``checkpoint`` (weights + config + the metrics below), ``metrics_file`` (validation accuracy over 600
episodes with its 95% interval: a DVC metric), ``train_info.json`` beside it (timings, threads, flags,
paths: not a metric) and ``history_file`` (one row per selection evaluation).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import torch

from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import load_split, read_manifest
from pipeline.fewshot.training import config_dict, meta_train
from pipeline.files import write_json_atomic
from pipeline.stages._common import stage_main
from pipeline.stages._schema import MetaTrainConfig

#: The keys of the training result that ``metrics_file`` holds; the others go to ``train_info.json``.
METRIC_KEYS = ("val_accuracy", "val_ci95", "val_episodes", "selection_val_accuracy", "selected_episode")


def run(cfg: MetaTrainConfig, overrides: list[str] = ()) -> dict:
    config = cfg.train
    torch.set_num_threads(cfg.threads)
    frame = read_manifest(cfg.images_dir)
    train = load_split(cfg.images_dir, "train", config.input_size, frame)
    val = load_split(cfg.images_dir, "val", config.input_size, frame)
    result = meta_train(train, val, config, progress=cfg.progress)
    metrics = {**result.metrics, "images_dir": cfg.images_dir}
    scores = {k: metrics[k] for k in METRIC_KEYS}  # no timings: the same training gives the same bytes
    save_checkpoint(cfg.checkpoint, result.network, normalisation=result.normalisation, config=config_dict(config), metrics=scores)
    write_json_atomic(cfg.metrics_file, scores, sort_keys=True)
    write_json_atomic(Path(cfg.metrics_file).with_name("train_info.json"),
                      {k: v for k, v in metrics.items() if k not in METRIC_KEYS}, sort_keys=True)
    pd.DataFrame(result.history).to_csv(cfg.history_file, index=False)
    print(
        f"validation accuracy {100 * metrics['val_accuracy']:.2f}% +- {100 * metrics['val_ci95']:.2f}% "
        f"({metrics['val_episodes']} episodes, {val.n_classes} held-out classes); "
        f"{metrics['episodes_trained']} episodes in {metrics['train_seconds']:.0f} s"
    )
    return metrics


def written(cfg: MetaTrainConfig, metrics: dict) -> list[str | Path]:
    return [cfg.checkpoint, cfg.metrics_file, Path(cfg.metrics_file).with_name("train_info.json"), cfg.history_file]


def main() -> None:
    stage_main("meta_train", run)
