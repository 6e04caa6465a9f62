"""Stage ``meta_train``: episodic meta-training of the Relation Network on the rendered training
classes, checkpoint selection on the validation classes (paper section 3.2.1; docs/fewshot.md).

    python -m pipeline meta_train [images_dir=...] [train.episodes=...]

Writes ``checkpoint`` (weights + config + metrics), ``metrics_file`` (validation accuracy over 600
episodes with its 95% interval) and ``history_file`` (one row per selection evaluation).
"""
from __future__ import annotations

import hydra
import pandas as pd
import torch
from omegaconf import DictConfig

from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import load_split, read_manifest
from pipeline.fewshot.training import TrainConfig, config_dict, meta_train
from pipeline.stages._common import CONF_DIR, build, check_keys, write_json_atomic

KEYS = {"images_dir": str, "checkpoint": str, "metrics_file": str, "history_file": str, "threads": int, "progress": bool, "train": dict}


def run(cfg: DictConfig) -> dict:
    plain = check_keys(cfg, KEYS, "meta_train")
    config = build(TrainConfig, plain["train"], "train")
    if plain["threads"] < 1:
        raise ValueError(f"meta_train: threads must be >= 1, got {plain['threads']}")
    torch.set_num_threads(plain["threads"])
    frame = read_manifest(plain["images_dir"])
    train = load_split(plain["images_dir"], "train", config.input_size, frame)
    val = load_split(plain["images_dir"], "val", config.input_size, frame)
    result = meta_train(train, val, config, progress=plain["progress"])
    metrics = {**result.metrics, "images_dir": plain["images_dir"]}
    save_checkpoint(plain["checkpoint"], result.network, normalisation=result.normalisation, config=config_dict(config), metrics=metrics)
    write_json_atomic(plain["metrics_file"], metrics, sort_keys=True)
    pd.DataFrame(result.history).to_csv(plain["history_file"], index=False)
    print(
        f"validation accuracy {100 * metrics['val_accuracy']:.2f}% +- {100 * metrics['val_ci95']:.2f}% "
        f"({metrics['val_episodes']} episodes, {val.n_classes} held-out classes); "
        f"{metrics['episodes_trained']} episodes in {metrics['train_seconds']:.0f} s -> {plain['checkpoint']}"
    )
    return metrics


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="meta_train")
def main(cfg: DictConfig) -> None:
    run(cfg)
