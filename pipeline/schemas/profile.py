"""The typed schema of the ``profile`` config group (``conf/profile/*.yaml``): the scale
of every stage (``paper``, ``smoke``), which the stages' schemas read through ``profile.<stage>``.
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field

from omegaconf import II

from pipeline.config.fields import same_key, setting


@dataclass
class RenderProfile:
    """The render stage's scale (its keys of the same names read these)."""

    n_train_classes: int = setting(ge=0)
    """Meta-training classes (the paper: miniImageNet's 64)."""
    n_val_classes: int = setting(ge=0)
    """Held-out validation classes that pick the checkpoint."""
    n_test_classes: int = setting(ge=0)
    """Held-out test classes that give the quoted accuracy (Ravi and Larochelle: 20)."""
    per_class: int = setting(ge=1)
    """Pictures per meta-training class."""
    views_per_obstacle: int = setting(ge=0)
    """Pictures per query obstacle in the colour test's larger query-like set (split ``views``; 0:
    none)."""
    workers: int = setting(ge=1)
    """Render processes (one renderer each); 1: in this process."""


@dataclass
class TrialsProfile:
    """The trials' scale (the keys ``runs`` and ``episodes`` and the generated layouts read these)."""

    runs: int = setting(ge=1)
    """Independent runs per cell (each with its own obstacle assignment and seed)."""
    episodes: int = setting(ge=1)
    """Episodes per run."""
    layouts: int = setting(ge=1)
    """Generated layouts per size of an experiment's layout sets (``generalisation.yaml`` reads it as each set's ``count``)."""
    layout_runs: int = setting(ge=1)
    """Runs per cell of an experiment over generated layouts (``generalisation.yaml``'s ``runs``)."""
    repetition_layouts: int = setting(ge=1)
    """Generated layouts per repetition count of ``conf/experiment/repetition.yaml``."""
    repetition_runs: int = setting(ge=1)
    """Runs per cell of ``repetition.yaml``."""


@dataclass
class MetaTrainProfile:
    """Meta-training's scale (``train.<key>`` of ``conf/meta_train.yaml`` reads these)."""

    episodes: int = setting(ge=1)
    """Training episodes of the Relation Network."""
    protonet_episodes: int = setting(ge=1)
    """Training episodes of the Prototypical Network (``model=protonet``)."""
    val_every: int = setting(ge=1)
    """Training episodes between model-selection evaluations."""
    val_episodes: int = setting(ge=1)
    """Model-selection episodes (validation classes only)."""
    eval_episodes: int = setting(ge=1)
    """Episodes of the reported accuracy and its 95% interval."""
    eval_queries: int = setting(ge=1)
    """Query pictures per class in those episodes."""


@dataclass
class AccuracyProfile:
    """The accuracy study's scale."""

    repeats: int = setting(ge=1)
    """Repetitions per substituted category (the paper: 100, giving x/800)."""


@dataclass
class Profile:
    """The scale of every stage: ``paper`` (the default of ``dvc repro``) or ``smoke``."""

    render: RenderProfile = field(default_factory=RenderProfile)
    """The render stage's scale."""
    trials: TrialsProfile = field(default_factory=TrialsProfile)
    """The trials' scale."""
    meta_train: MetaTrainProfile = field(default_factory=MetaTrainProfile)
    """Meta-training's scale."""
    accuracy: AccuracyProfile = field(default_factory=AccuracyProfile)
    """The accuracy study's scale."""


def profile_key(section: str, name: str):
    """A stage key whose default is the profile's ``<section>.<name>`` (``runs`` of the trials reads
    ``profile.trials.runs``): the profile's key declares its range and words."""
    return same_key(typing.get_type_hints(Profile)[section], name, II(f"profile.{section}.{name}"))
