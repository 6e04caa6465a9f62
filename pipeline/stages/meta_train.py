"""Stage ``meta_train``: episodic meta-training of a few-shot recogniser, checkpoint chosen on held-out classes.

The Relation Network (``model=relation_net``, the default) or a Prototypical Network
(``model=protonet``), trained episodically on the training classes (the rendered ones, or your own
with ``data=folder``), checkpoint selected on the validation classes (paper section 3.2.1;
docs/fewshot.md).

    python -m pipeline meta_train [images_dir=...] [train.episodes=...]
    python -m pipeline meta_train train.model=protonet checkpoint=datasets/models/protonet.pt ...   # dvc.yaml's meta_train_protonet
    python -m pipeline meta_train data=folder data.train_dir=DIR data.val_dir=DIR   # any folder-per-class trees

Writes ``checkpoint`` (weights + config + the metrics below), ``metrics_file`` (validation accuracy over 600
episodes with its 95% interval: a DVC metric), ``<checkpoint stem>.train_info.json`` beside the
checkpoint (timings, threads, flags, paths: not a metric; named after the checkpoint, so two
trainings into one folder keep theirs) and ``history_file`` (one row per selection evaluation).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import torch

from pipeline.errors import ConfigError
from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import PictureSet, load_folder, load_split, read_manifest
from pipeline.fewshot.episodes import require_episodes
from pipeline.fewshot.training import config_dict, meta_train
from pipeline.files import write_json_atomic
from pipeline.stages._common import stage_main
from pipeline.stages._schema import MetaTrainConfig

#: The keys of the training result that ``metrics_file`` holds; the others go to :func:`info_file`.
METRIC_KEYS = (
    "val_accuracy",
    "val_ci95",
    "val_episodes",
    "selection_val_accuracy",
    "selected_episode",
)


def picture_sets(
    cfg: MetaTrainConfig, overrides: list[str]
) -> tuple[PictureSet, PictureSet, dict[str, str]]:
    """The training and validation classes at the model's input size, and where they came from;
    refuses keys the chosen ``data`` source does not read, and splits too small for the episodes."""
    size, data = cfg.train.input_size, cfg.data
    given = {o.lstrip("+~").split("=")[0] for o in overrides}
    if data.source == "folder":
        if "images_dir" in given:
            raise ConfigError(
                "config key 'images_dir': data=folder reads data.train_dir and data.val_dir, "
                "not images_dir; leave it out"
            )
        for key in ("train_dir", "val_dir"):
            if not getattr(data, key):
                raise ConfigError(
                    f"config key 'data.{key}': data=folder needs it (data.{key}=<folder-per-class tree>)"
                )
        for key in ("train_dir", "val_dir"):  # both checked before either is read
            try:
                is_dir = Path(getattr(data, key)).resolve(strict=True).is_dir()
            except (OSError, RuntimeError):  # missing, or a symbolic link loop
                is_dir = False
            if not is_dir:
                raise ConfigError(
                    f"config key 'data.{key}': {getattr(data, key)} is not a folder (missing, a "
                    "file, or a symbolic link loop)"
                )
        if Path(data.train_dir).resolve() == Path(data.val_dir).resolve():
            raise ConfigError(
                "config key 'data.val_dir': it is data.train_dir; the validation classes must be held out"
            )
        train, val = (
            load_folder(getattr(data, key), size, progress=cfg.progress)
            for key in ("train_dir", "val_dir")
        )
        shared = sorted(set(train.class_names) & set(val.class_names))
        if shared:
            raise ConfigError(
                f"config key 'data.val_dir': classes {', '.join(shared[:5])} are in data.train_dir too; "
                "the validation classes must be held out"
            )
        source = {"train_dir": data.train_dir, "val_dir": data.val_dir}
    else:
        for key in ("train_dir", "val_dir"):
            if getattr(data, key) is not None:
                raise ConfigError(
                    f"config key 'data.{key}': read only with data=folder (this run has data=rendered, "
                    "the train and val splits of images_dir)"
                )
        frame = read_manifest(cfg.images_dir)
        train = load_split(cfg.images_dir, "train", size, frame)
        val = load_split(cfg.images_dir, "val", size, frame)
        source = {"images_dir": cfg.images_dir}
    where = source.get("train_dir", cfg.images_dir), source.get("val_dir", cfg.images_dir)
    c = cfg.train
    require_episodes(
        train.by_class(),
        train.class_names,
        c.n_way,
        c.k_shot + c.n_query,
        f"training classes ({where[0]})",
    )
    require_episodes(
        val.by_class(),
        val.class_names,
        c.n_way,
        c.k_shot + c.eval_queries,
        f"validation classes ({where[1]})",
    )
    return train, val, source


def refuse_idle_keys(cfg: MetaTrainConfig, overrides: list[str]) -> None:
    """``train.relation_padding`` shapes g_phi, which a Prototypical Network does not have: given
    on the command line with ``train.model=protonet`` it is refused (any value but 0 is refused by
    :class:`~pipeline.fewshot.settings.TrainConfig` itself)."""
    given = {o.lstrip("+~").split("=")[0] for o in overrides}
    if cfg.train.model == "protonet" and "train.relation_padding" in given:
        raise ConfigError(
            "config key 'train.relation_padding': the Prototypical Network has no relation module "
            "g_phi, so the key cannot apply with train.model=protonet; leave it out"
        )


def info_file(checkpoint: str | Path) -> Path:
    """The training's timings, threads, flags and paths: ``<checkpoint stem>.train_info.json``."""
    return Path(checkpoint).with_suffix(".train_info.json")


def run(cfg: MetaTrainConfig, overrides: list[str] = ()) -> dict:
    config = cfg.train
    refuse_idle_keys(cfg, list(overrides))
    torch.set_num_threads(cfg.threads)
    train, val, source = picture_sets(cfg, list(overrides))
    result = meta_train(train, val, config, progress=cfg.progress)
    metrics = {**result.metrics, **source}
    scores = {
        k: metrics[k] for k in METRIC_KEYS
    }  # no timings: the same training gives the same bytes
    save_checkpoint(
        cfg.checkpoint,
        result.network,
        normalisation=result.normalisation,
        config=config_dict(config),
        metrics=scores,
    )
    write_json_atomic(cfg.metrics_file, scores, sort_keys=True)
    write_json_atomic(
        info_file(cfg.checkpoint),
        {k: v for k, v in metrics.items() if k not in METRIC_KEYS},
        sort_keys=True,
    )
    pd.DataFrame(result.history).to_csv(cfg.history_file, index=False)
    print(
        f"validation accuracy {100 * metrics['val_accuracy']:.2f}% +- {100 * metrics['val_ci95']:.2f}% "
        f"({metrics['val_episodes']} episodes, {val.n_classes} held-out classes); "
        f"{metrics['episodes_trained']} episodes in {metrics['train_seconds']:.0f} s"
    )
    return metrics


def written(cfg: MetaTrainConfig, metrics: dict) -> list[str | Path]:
    return [
        cfg.checkpoint,
        cfg.metrics_file,
        info_file(cfg.checkpoint),
        cfg.history_file,
    ]


def main() -> None:
    stage_main("meta_train", run)
