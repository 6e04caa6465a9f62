"""Stage ``meta_train``: episodic meta-training of a few-shot recogniser, checkpoint chosen on held-out classes.

The Relation Network (``model=relation_net``, the default) or a Prototypical Network
(``model=protonet``), trained episodically on the training classes (the rendered ones, or your own
with ``data=folder``), checkpoint selected on the validation classes and measured on the test
classes (paper section 3.2.1; Ravi and Larochelle's train / validation / test split;
docs/fewshot.md).

    python -m pipeline meta_train [images_dir=...] [train.episodes=...]
    python -m pipeline meta_train train.model=protonet checkpoint=datasets/models/protonet.pt ...   # dvc.yaml's meta_train_protonet
    python -m pipeline meta_train data=folder data.train_dir=DIR data.val_dir=DIR data.test_dir=DIR   # any folder-per-class trees

Writes ``checkpoint`` (weights + config + every figure below), ``metrics_file`` (the quoted figure
only: test accuracy over 600 episodes with its 95% interval as ``accuracy``,
``ci_lower``, ``ci_upper``), ``<checkpoint stem>.validation.json`` beside the checkpoint (validation
accuracy, the selection's figures and the test's again: what the report reads; not a metric),
``<checkpoint stem>.train_info.json`` (timings, threads, kernel path, flags, paths: not a metric;
named after the checkpoint, so two trainings into one folder keep theirs) and ``history_file`` (one row per
selection evaluation). The CPU kernels are pinned to the AVX2 path before training
(``pipeline/kernels.TRAINING``), so a seed gives the same weights on any machine with AVX2, not
only on machines of one instruction set.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import torch

from pipeline.config.fields import refuse
from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import PictureSet, load_folder, load_split, read_manifest
from pipeline.fewshot.episodes import require_episodes
from pipeline.fewshot.training import config_dict, meta_train
from pipeline.files import write_json_atomic
from pipeline.kernels import TRAINING, kernel_path, pin_kernels
from pipeline.schemas.fewshot import MetaTrainConfig
from pipeline.stages import stage_main

#: The keys of the training result that the checkpoint and ``<checkpoint stem>.validation.json``
#: hold (deterministic for a seed); the others (timings) go to :func:`info_file`.
SCORE_KEYS = (
    "test_accuracy",
    "test_ci95",
    "test_episodes",
    "val_accuracy",
    "val_ci95",
    "val_episodes",
    "selection_val_accuracy",
    "selected_episode",
    "n_train_classes",
    "n_val_classes",
    "n_test_classes",
)
FOLDER_KEYS = ("train_dir", "val_dir", "test_dir")
SPLIT_WORDS = {"train_dir": "training", "val_dir": "validation", "test_dir": "test"}


def quoted_metrics(scores: dict) -> dict[str, float]:
    """``metrics_file``'s content: the test accuracy and its 95% interval, nothing else (so
    ``dvc metrics show <metrics_file>`` prints one column per figure a person compares, the
    interval's ends in order: DVC sorts the keys)."""
    acc, ci = scores["test_accuracy"], scores["test_ci95"]
    return {"accuracy": acc, "ci_lower": acc - ci, "ci_upper": acc + ci}


def _folder_sets(cfg: MetaTrainConfig, given: set[str]) -> tuple[list[PictureSet], dict[str, str]]:
    """``data=folder``: the three trees, each checked before any is read; refuses a missing key
    (the test classes too: the quoted accuracy is theirs), one tree given twice and a class in two
    trees."""
    data, size = cfg.data, cfg.train.input_size
    if "images_dir" in given:
        refuse(
            "images_dir",
            "data=folder reads data.train_dir, data.val_dir and "
            "data.test_dir, not images_dir; leave it out",
        )
    for key in FOLDER_KEYS:
        if not getattr(data, key):
            refuse(
                f"data.{key}",
                f"data=folder needs it (data.{key}=<folder-per-class tree "
                f"of the {SPLIT_WORDS[key]} classes>"
                + (
                    "; the quoted accuracy is the test classes', held out from training and selection)"
                    if key == "test_dir"
                    else ")"
                ),
            )
    for key in FOLDER_KEYS:  # all checked before any is read
        try:
            is_dir = Path(getattr(data, key)).resolve(strict=True).is_dir()
        except (OSError, RuntimeError):  # missing, or a symbolic link loop
            is_dir = False
        if not is_dir:
            refuse(
                f"data.{key}",
                f"{getattr(data, key)} is not a folder (missing, a file, or a symbolic link loop)",
            )
    for i, key in enumerate(FOLDER_KEYS):
        for earlier in FOLDER_KEYS[:i]:
            if Path(getattr(data, key)).resolve() == Path(getattr(data, earlier)).resolve():
                refuse(
                    f"data.{key}",
                    f"it is data.{earlier}; the {SPLIT_WORDS[key]} classes must be held out",
                )
    sets = [load_folder(getattr(data, key), size, progress=cfg.progress) for key in FOLDER_KEYS]
    for i, key in enumerate(FOLDER_KEYS):
        for j, earlier in enumerate(FOLDER_KEYS[:i]):
            shared = sorted(set(sets[i].class_names) & set(sets[j].class_names))
            if shared:
                refuse(
                    f"data.{key}",
                    f"classes {', '.join(shared[:5])} are in data.{earlier} "
                    f"too; the {SPLIT_WORDS[key]} classes must be held out",
                )
    return sets, {key: getattr(data, key) for key in FOLDER_KEYS}


def picture_sets(
    cfg: MetaTrainConfig, overrides: list[str]
) -> tuple[PictureSet, PictureSet, PictureSet, dict[str, str]]:
    """The training, validation and test classes at the model's input size, and where they came
    from; refuses keys the chosen ``data`` source does not read, and splits too small for the
    episodes."""
    size, data = cfg.train.input_size, cfg.data
    given = {o.lstrip("+~").split("=")[0] for o in overrides}
    if data.source == "folder":
        (train, val, test), source = _folder_sets(cfg, given)
    else:
        for key in FOLDER_KEYS:
            if getattr(data, key) is not None:
                refuse(
                    f"data.{key}",
                    "read only with data=folder (this run has data=rendered, "
                    "the train, val and test splits of images_dir)",
                )
        frame = read_manifest(cfg.images_dir)
        train, val, test = (
            load_split(cfg.images_dir, s, size, frame) for s in ("train", "val", "test")
        )
        source = {"images_dir": cfg.images_dir}
    c = cfg.train
    for key, pictures, per_class in (
        ("train_dir", train, c.k_shot + c.n_query),
        ("val_dir", val, c.k_shot + c.eval_queries),
        ("test_dir", test, c.k_shot + c.eval_queries),
    ):
        require_episodes(
            pictures.by_class(),
            pictures.class_names,
            c.n_way,
            per_class,
            f"{SPLIT_WORDS[key]} classes ({source.get(key, cfg.images_dir)})",
        )
    return train, val, test, source


def refuse_idle_keys(cfg: MetaTrainConfig, overrides: list[str]) -> None:
    """``train.relation_padding`` shapes g_phi, which a Prototypical Network does not have: given
    on the command line with ``train.model=protonet`` it is refused (any value but 0 is refused by
    :class:`~pipeline.fewshot.settings.TrainConfig` itself)."""
    given = {o.lstrip("+~").split("=")[0] for o in overrides}
    if cfg.train.model == "protonet" and "train.relation_padding" in given:
        refuse(
            "train.relation_padding",
            "the Prototypical Network has no relation module "
            "g_phi, so the key cannot apply with train.model=protonet; leave it out",
        )


def info_file(checkpoint: str | Path) -> Path:
    """The training's timings, threads, flags and paths: ``<checkpoint stem>.train_info.json``."""
    return Path(checkpoint).with_suffix(".train_info.json")


def validation_file(checkpoint: str | Path) -> Path:
    """Validation, selection and test figures (``SCORE_KEYS``): ``<checkpoint stem>.validation.json``."""
    return Path(checkpoint).with_suffix(".validation.json")


def run(cfg: MetaTrainConfig, overrides: list[str] = ()) -> dict:
    config = cfg.train
    refuse_idle_keys(cfg, list(overrides))
    pin_kernels(TRAINING)  # one kernel path on every AVX2 machine: the same seed, the same weights
    torch.set_num_threads(cfg.threads)
    train, val, test, source = picture_sets(cfg, list(overrides))
    result = meta_train(train, val, config, progress=cfg.progress, test=test)
    metrics = {**result.metrics, **source, "cpu_kernels": kernel_path()}
    scores = {
        k: metrics[k] for k in SCORE_KEYS
    }  # no timings: the same training gives the same bytes
    save_checkpoint(
        cfg.checkpoint,
        result.network,
        normalisation=result.normalisation,
        config=config_dict(config),
        metrics=scores,
    )
    write_json_atomic(cfg.metrics_file, quoted_metrics(scores), sort_keys=True)
    write_json_atomic(validation_file(cfg.checkpoint), scores, sort_keys=True)
    write_json_atomic(
        info_file(cfg.checkpoint),
        {k: v for k, v in metrics.items() if k not in SCORE_KEYS},
        sort_keys=True,
    )
    pd.DataFrame(result.history).to_csv(cfg.history_file, index=False)
    print(
        f"test accuracy {100 * metrics['test_accuracy']:.2f}% +- {100 * metrics['test_ci95']:.2f}% "
        f"({metrics['test_episodes']} episodes, {test.n_classes} test classes); validation "
        f"{100 * metrics['val_accuracy']:.2f}% +- {100 * metrics['val_ci95']:.2f}% "
        f"({val.n_classes} classes, which chose the checkpoint); "
        f"{metrics['episodes_trained']} episodes in {metrics['train_seconds']:.0f} s"
    )
    return metrics


def written(cfg: MetaTrainConfig, metrics: dict) -> list[str | Path]:
    return [
        cfg.checkpoint,
        cfg.metrics_file,
        validation_file(cfg.checkpoint),
        info_file(cfg.checkpoint),
        cfg.history_file,
    ]


def main() -> None:
    stage_main("meta_train", run)
