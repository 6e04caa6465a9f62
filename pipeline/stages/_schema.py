"""The typed schema of every stage's config (Hydra structured configs, registered in the ConfigStore).

``pipeline/conf/<stage>.yaml`` names its schema first in its defaults list (``- trials_schema``) and gives the
values; the dataclasses here give each key's type, range or choices and, in the string under it,
its description (:mod:`pipeline.schema`). Hydra refuses wrong types and unknown keys while
composing; :func:`pipeline.schema.check` refuses values out of range; ``python -m pipeline <stage>
--help`` prints the same declarations (``pipeline/stages/_help.py``). The groups are typed through
their parent's field: ``method`` by :class:`~pipeline.rl.methods.MethodSpec`, ``profile`` by
:class:`Profile`, ``experiment`` by :class:`~pipeline.stages._experiment_schema.Experiment`,
``data`` by :class:`DataConfig`; a recogniser is typed by the signature of its ``_target_``
(``pipeline.stages._recognisers``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from omegaconf import II, MISSING

from pipeline.fewshot.settings import StudyConfig, TrainConfig
from pipeline.rl.methods import MethodSpec
from pipeline.schema import setting
from pipeline.stages._experiment_schema import (  # noqa: F401  (the experiment group's schema)
    RULES,
    SUBSTITUTION_WAYS,
    SUPPORT_MODES,
    WORLDS,
    Cell,
    Experiment,
    Layouts,
    LayoutSet,
    RobotConfig,
)
from pipeline.stages._profile_schema import Profile
from pipeline.stages._render_schema import RenderConfig  # the render stage's schema

VIEWERS = ("none", "web", "native")
RECORD_LEVELS = ("steps", "episodes", "none")
DATA_SOURCES = ("rendered", "folder")


# ---------------------------------------------------------------- trials
@dataclass
class TrialsConfig:
    """``python -m pipeline trials``: independent runs of a method on a maze (or every cell of an experiment), every episode recorded to MCAP."""

    profile: Profile = field(default_factory=Profile)
    """The scale (``pipeline/conf/profile/``): ``runs`` and ``episodes`` default to its ``trials`` keys."""
    method: MethodSpec = field(default_factory=MethodSpec)
    """The method (``pipeline/conf/method/``): its file over the base method, then ``method.<field>=``."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``pipeline/conf/recogniser/``): ``_target_`` and its arguments."""
    experiment: Experiment | None = None
    """An experiment (``+experiment=<name>``, ``pipeline/conf/experiment/``): several cells, one run each."""
    maze: str = setting(nonempty=True)
    """A built-in layout (``pipeline/conf/mazes/<name>.txt``), a path to a layout file, or a generated layout ``random:<W>x<H>:<obstacles>:<seed>[:unique]`` (``pipeline/world/generate.py``)."""
    substitution: int = setting(choices=SUBSTITUTION_WAYS)
    """Dynamic support set: substitution way 1-4 (section 3.3); used by methods with dynamic_support."""
    world: str = setting("grid", choices=WORLDS)
    """``grid``: the grid world (the paper's); ``robot3d``: the camera robot in MuJoCo (docs/robot3d.md)."""
    robot: RobotConfig = field(default_factory=RobotConfig)
    """The robot world's settings; read only with ``world=robot3d``."""
    rule: str = setting("paper", choices=RULES)
    """When a picture stops the robot (methods that recognise pictures), the same in every world: ``paper`` (the prediction names the obstacle's true category), ``open_set`` (its top score reaches ``threshold``) or ``range`` (the range sensor alone: every occupied cell)."""
    threshold: float = setting(0.5, gt=0, le=1)
    """``rule=open_set``: the top score at which a picture stops the robot."""
    support: str = setting(choices=SUPPORT_MODES)
    """``restore`` the support set before each run, or ``carry`` it over (long-term autonomy)."""
    images_dir: str | None = None
    """Rendered pictures (the render stage's folder) whose query pictures and initial support set the records keep, for recognisers without pictures of their own (oracle, fixed_accuracy); relation_net records those of its ``recogniser.images_dir``."""
    runs: int = setting(II("profile.trials.runs"), ge=1)
    """Independent runs (each with its own obstacle assignment and seed)."""
    episodes: int = setting(II("profile.trials.episodes"), ge=1)
    """Episodes per run."""
    seed: int = setting(ge=0)
    """Seeds every run: run ``r`` draws its placement, exploration and recogniser from ``(seed, r)``."""
    out: str = setting(nonempty=True)
    """Writes ``<out>/summary.json`` (+ ``records.mcap``); an experiment: ``<out>/<cell>/``."""
    overwrite: bool = MISSING
    """Replace results already in ``out``; without it such an ``out`` is refused (dvc.yaml's trials stages give it: DVC keeps their outs, ``persist``)."""
    index_file: str | None = None
    """An experiment: every file of ``out`` with its SHA-256 (``pipeline.files.write_index``), for dvc.yaml."""
    metrics_dir: str | None = None
    """An experiment's DVC metrics go to this folder (replaced): one small file per cell, or per template and size over generated layouts (``pipeline/stages/_metrics.py``)."""
    timing_file: str | None = None
    """Each cell's trial seconds are written here (kept out of ``out``, which is byte-reproducible)."""
    record: str = setting(choices=RECORD_LEVELS)
    """What the MCAP records hold (docs/records.md "Record levels"): ``steps`` every step, ``episodes`` per-episode summaries and every recognition, substitution and unsafe pair, ``none`` no record file."""
    flush_every: int = setting(ge=1)
    """Episodes per MCAP chunk (what a killed run may lose)."""
    progress: bool = MISSING
    """Print progress (on stderr)."""
    threads: int = setting(ge=0)
    """numba threads; 0 = all cores (divided among the ``workers``)."""
    workers: int = setting(1, ge=1)
    """Processes that run an experiment's cells side by side (each builds the recogniser once); the results are the same bytes for any number."""


# ---------------------------------------------------------------- meta_train, accuracy
@dataclass
class DataConfig:
    """Where meta-training's classes come from (``pipeline/conf/data/``): ``rendered``, the render stage's
    ``train``, ``val`` and ``test`` splits in ``images_dir``; ``folder``, three folder-per-class trees
    (:func:`pipeline.fewshot.data.load_folder`), such as miniImageNet's."""

    source: str = setting(choices=DATA_SOURCES)
    """Where the classes come from (set by the group: ``data=rendered`` or ``data=folder``)."""
    train_dir: str | None = None
    """``data=folder``: the training classes, ``<train_dir>/<class>/<picture>``."""
    val_dir: str | None = None
    """``data=folder``: the validation classes (model selection; their accuracy is reported beside the test's)."""
    test_dir: str | None = None
    """``data=folder``: the test classes (the quoted accuracy); required: without it the run is refused."""


@dataclass
class MetaTrainConfig:
    """``python -m pipeline meta_train``: meta-train the Relation Network (or, with
    ``model=protonet``, a Prototypical Network) and write its checkpoint and validation metrics."""

    profile: Profile = field(default_factory=Profile)
    """The scale (``pipeline/conf/profile/``): training and validation episodes default to its ``meta_train`` keys."""
    data: DataConfig = field(default_factory=DataConfig)
    """Where the classes come from (``pipeline/conf/data/``)."""
    images_dir: str = setting(nonempty=True)
    """``data=rendered``: the render stage's output, whose train and val splits are read."""
    checkpoint: str = setting(nonempty=True)
    """The selected checkpoint (set by the ``model`` group)."""
    metrics_file: str = setting(nonempty=True)
    """Its test accuracy and 95% interval (DVC metrics: ``accuracy``, ``ci_low``, ``ci_high``;
    ``<checkpoint stem>.validation.json`` (validation and selection) and ``.train_info.json``
    (timings) go beside the checkpoint)."""
    history_file: str = setting(nonempty=True)
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
    """The scale (``pipeline/conf/profile/``): ``study.repeats`` defaults to its ``accuracy.repeats``."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``pipeline/conf/recogniser/``), as in the trials."""
    out_dir: str = setting(nonempty=True)
    """``baseline.csv``, ``table1.csv``, ``table2.csv`` and ``summary.json``."""
    threads: int = setting(ge=1)
    """torch intra-op threads."""
    progress: bool = MISSING
    """Show a progress bar (on stderr)."""
    study: StudyConfig = field(default_factory=StudyConfig)
    """The study's settings."""


# ---------------------------------------------------------------- replay, report
@dataclass
class ReplayConfig:
    """``python -m pipeline replay``: one recorded episode (or a whole run) in Rerun."""

    file: str = setting(nonempty=True)
    """An ``.mcap`` record file (or the ``.mcap.partial`` of a killed run)."""
    run: int = setting(ge=0)
    """The run to replay."""
    episode: int | None = setting(None, ge=0)
    """The episode to replay; none: the run's first episode with a recognition."""
    whole_run: bool = MISSING
    """Every episode of the run on one timeline (refused together with ``episode``)."""
    out: str | None = None
    """The ``.rrd`` to write; none: ``replays/<experiment>-<cell>-run<run>-ep<episode>.rrd``."""
    viewer: str = setting(choices=VIEWERS)
    """Then open the recording: ``none``, ``web`` (serve it to a browser) or ``native`` (needs a display)."""
    bind: str = setting(nonempty=True)
    """IP address the web viewer listens on; off the loopback only with ``allow_remote``."""
    allow_remote: bool = MISSING
    """Allow a ``bind`` reachable from other machines (``0.0.0.0``, a LAN address); warns."""
    web_port: int = setting(ge=0, le=65535)
    """HTTP port of the web viewer; 0 picks a free one (printed)."""
    grpc_port: int = setting(ge=0, le=65535)
    """gRPC port that serves the recording to the viewer; 0 picks a free one."""


@dataclass
class ReportConfig:
    """``python -m pipeline report``: rebuild the report from the recorded data alone."""

    runs_dir: str = setting(nonempty=True)
    """The trials' records: ``<runs_dir>/<experiment>/<cell>/records.mcap``."""
    accuracy_dir: str = setting(nonempty=True)
    """The accuracy stage's data files (the Relation Network's)."""
    model_metrics: str = setting(nonempty=True)
    """The Relation Network's validation metrics (meta_train)."""
    protonet_accuracy_dir: str = setting(nonempty=True)
    """The Prototypical Network's accuracy study, shown beside the Relation Network's (Tables 1-2)."""
    protonet_metrics: str = setting(nonempty=True)
    """The Prototypical Network's validation metrics (meta_train model=protonet)."""
    contact_dir: str = setting(nonempty=True)
    """The render stage's contact sheets, copied to the report's figures."""
    out: str = setting(nonempty=True)
    """``index.md``, ``tables/`` and ``figures/`` (replaced only by a complete build)."""
    allow_missing: bool = MISSING
    """Build without experiments or cells that have no complete records (listed at the top)."""
    allow_mixed_scales: bool = MISSING
    """Build from cells recorded at different scales (profiles), each named at the top."""


#: Stage name -> its schema (``pipeline/conf/<stage>.yaml`` lists ``<stage>_schema`` first in its defaults).
SCHEMAS = {
    "trials": TrialsConfig,
    "render": RenderConfig,
    "meta_train": MetaTrainConfig,
    "accuracy": AccuracyConfig,
    "replay": ReplayConfig,
    "report": ReportConfig,
}


def register() -> None:
    """Store every stage's schema in Hydra's ConfigStore as ``<stage>_schema`` (before composing)."""
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    for stage, schema in SCHEMAS.items():
        cs.store(name=f"{stage}_schema", node=schema)
