"""The schemas of the few-shot stages: :class:`MetaTrainConfig` (``conf/meta_train.yaml``,
its ``data`` group typed by :class:`DataConfig`) and :class:`AccuracyConfig`
(``conf/accuracy.yaml``); the conventions: ``pipeline/schemas/__init__.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from pipeline.config.fields import setting
from pipeline.fewshot.settings import StudyConfig, TrainConfig
from pipeline.schemas.profile import Profile

DATA_SOURCES = ("rendered", "folder")


@dataclass
class DataConfig:
    """Where meta-training's classes come from (``conf/data/``): ``rendered``, the render stage's
    ``train``, ``val`` and ``test`` splits in ``images_dir``; ``folder``, three folder-per-class trees
    (:func:`pipeline.fewshot.data.load_folder`), such as miniImageNet's."""

    source: str = setting(choices=DATA_SOURCES)
    """Where the classes come from (set by the group: ``data=rendered`` or ``data=folder``)."""
    train_dir: str | None = setting(None, path=True)
    """``data=folder``: the training classes, ``<train_dir>/<class>/<picture>``."""
    val_dir: str | None = setting(None, path=True)
    """``data=folder``: the validation classes (model selection; their accuracy is reported beside the test's)."""
    test_dir: str | None = setting(None, path=True)
    """``data=folder``: the test classes (the quoted accuracy); required: without it the run is refused."""


@dataclass
class MetaTrainConfig:
    """``python -m pipeline meta_train``: meta-train the Relation Network (or, with
    ``model=protonet``, a Prototypical Network) and write its checkpoint and validation metrics."""

    profile: Profile = field(default_factory=Profile)
    """The scale (``conf/profile/``): training and validation episodes default to its ``meta_train`` keys."""
    data: DataConfig = field(default_factory=DataConfig)
    """Where the classes come from (``conf/data/``)."""
    images_dir: str = setting(nonempty=True, path=True)
    """``data=rendered``: the render stage's output, whose train and val splits are read."""
    checkpoint: str = setting(nonempty=True, path=True)
    """The selected checkpoint (set by the ``model`` group)."""
    metrics_file: str = setting(nonempty=True, path=True)
    """Its test accuracy and 95% interval (``accuracy``, ``ci_lower``, ``ci_upper``;
    ``<checkpoint stem>.validation.json`` (validation and selection) and ``.train_info.json``
    (timings) go beside the checkpoint)."""
    history_file: str = setting(nonempty=True, path=True)
    """The training history, one row per evaluation (CSV)."""
    threads: int = setting(ge=1)
    """torch intra-op threads."""
    progress: bool = MISSING
    """Show a progress bar (on stderr)."""
    train: TrainConfig = field(default_factory=TrainConfig)
    """The meta-training hyperparameters (``train.model`` is set by the ``model`` group)."""


@dataclass
class AccuracyConfig:
    """``python -m pipeline accuracy``: the few-shot accuracy study (Tables 1 and 2)."""

    profile: Profile = field(default_factory=Profile)
    """The scale (``conf/profile/``): ``study.repeats`` defaults to its ``accuracy.repeats``."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``conf/recogniser/``), as in the trials."""
    out_dir: str = setting(nonempty=True, path=True)
    """``baseline.csv``, ``table1.csv``, ``table2.csv``, ``draws.csv``, ``families.csv`` and
    ``summary.json``."""
    threads: int = setting(ge=1)
    """torch intra-op threads."""
    progress: bool = MISSING
    """Show a progress bar (on stderr)."""
    study: StudyConfig = field(default_factory=StudyConfig)
    """The study's settings."""
