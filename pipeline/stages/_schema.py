"""The typed schema of every stage's config (Hydra structured configs, registered in the ConfigStore).

``conf/<stage>.yaml`` names its schema first in its defaults list (``- trials_schema``) and gives the
values; the dataclasses here give the types, ranges and documentation. Hydra refuses wrong types and
unknown keys while composing; :func:`pipeline.schema.check` refuses values out of range. The groups
are typed through their parent's field: ``method`` by :class:`~pipeline.rl.methods.MethodSpec`,
``profile`` by :class:`Profile`, ``experiment`` by :class:`Experiment`; a recogniser is typed by the
signature of its ``_target_`` (``pipeline.stages._recognisers``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import II, MISSING

from pipeline.errors import ConfigError
from pipeline.fewshot.accuracy_study import StudyConfig
from pipeline.fewshot.settings import TrainConfig
from pipeline.report.spec import ReportSpec
from pipeline.rl.methods import MethodSpec
from pipeline.schema import setting
from pipeline.world.layout_sets import LayoutSetError, expand

SUPPORT_MODES = ("restore", "carry")
SUBSTITUTION_WAYS = (1, 2, 3, 4)
VIEWERS = ("none", "web", "native")
RECORD_LEVELS = ("steps", "episodes", "none")
DATA_SOURCES = ("rendered", "folder")


# ---------------------------------------------------------------- profile (conf/profile/*.yaml)
@dataclass
class RenderProfile:
    n_train_classes: int = setting(ge=0)
    n_val_classes: int = setting(ge=0)
    per_class: int = setting(ge=1)
    workers: int = setting(ge=1)


@dataclass
class TrialsProfile:
    runs: int = setting(ge=1)
    episodes: int = setting(ge=1)
    layouts: int = setting(ge=1)
    """Generated layouts per size of an experiment's layout sets (``conf/experiment/generalisation.yaml``
    reads it as each set's ``count``)."""
    layout_runs: int = setting(ge=1)
    """Runs per cell of an experiment over generated layouts (``generalisation.yaml``'s ``runs``)."""


@dataclass
class MetaTrainProfile:
    episodes: int = setting(ge=1)
    protonet_episodes: int = setting(ge=1)
    """Training episodes of the Prototypical Network (``model=protonet``): it levels off sooner."""
    val_every: int = setting(ge=1)
    val_episodes: int = setting(ge=1)
    eval_episodes: int = setting(ge=1)
    eval_queries: int = setting(ge=1)


@dataclass
class AccuracyProfile:
    repeats: int = setting(ge=1)


@dataclass
class Profile:
    """The scale of every stage: ``paper`` (the default of ``dvc repro``) or ``smoke``."""

    render: RenderProfile = field(default_factory=RenderProfile)
    trials: TrialsProfile = field(default_factory=TrialsProfile)
    meta_train: MetaTrainProfile = field(default_factory=MetaTrainProfile)
    accuracy: AccuracyProfile = field(default_factory=AccuracyProfile)


# ---------------------------------------------------------------- trials
@dataclass
class Cell:
    """One cell of an experiment: a method on a maze. Keys left out come from the top level
    (the experiment file's globals or the command line); keys given here are pinned."""

    method: str = setting(nonempty=True)
    """A method of ``conf/method/``."""
    maze: str | None = None
    substitution: int | None = setting(None, choices=SUBSTITUTION_WAYS)
    support: str | None = setting(None, choices=SUPPORT_MODES)
    params: dict[str, Any] = field(default_factory=dict)
    """Method fields this cell pins (``{alpha: 0.05}``); the command line does not change them."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """Recogniser arguments this cell pins (``{p: 0.3}``) over the top level's recogniser
    (``recogniser=<name>``, ``recogniser.<arg>=``), checked against that recogniser's parameters;
    only for methods that recognise pictures. The command line does not change them."""
    recogniser_group: str | None = None
    """A recogniser of ``conf/recogniser/`` (``protonet``) this cell runs instead of the top level's;
    the top level's recogniser arguments do not reach it, its own ``recogniser`` pins do."""


@dataclass
class LayoutSet:
    """``count`` generated layouts of one size (``pipeline/world/layout_sets.py``): the mazes
    ``random:<size>:<obstacles>:<seed + k>[:unique]``, ``k = 0 .. count-1``."""

    size: str = setting(nonempty=True)
    """``<W>x<H>`` (W wide, H high)."""
    obstacles: int = setting(ge=0)
    count: int = setting(ge=1)
    seed: int = setting(0, ge=0)
    """The first layout's seed; layout ``k`` has seed ``seed + k``."""
    unique: bool = True
    """The paper's kind of layout: a single shortest path lined by obstacles (``:unique``)."""


@dataclass
class Layouts:
    """Cell templates crossed with sets of generated layouts: cell ``<template>_<size>_L<seed>`` is
    the template on the layout of ``size`` with that seed."""

    sizes: list[LayoutSet] = field(default_factory=list)
    cells: dict[str, Cell] = field(default_factory=dict)
    """Templates: cells without a maze (each generated cell gets its layout's)."""


@dataclass
class Experiment:
    """``conf/experiment/<name>.yaml``: the cells, and how the report presents them."""

    name: str = setting(nonempty=True)
    cells: dict[str, Cell] = field(default_factory=dict)
    layouts: Layouts | None = None
    """Cells over generated layouts (``experiment.layouts``), besides the ``cells`` listed by hand."""

    def all_cells(self) -> dict[str, Cell]:
        """The cells listed by hand, then those of ``layouts`` (in set, layout, template order);
        a set that cannot be met, a template that pins a maze or a name given twice is refused
        (:class:`~pipeline.errors.ConfigError` naming the key)."""
        if self.layouts is None:
            return dict(self.cells)
        for name, template in self.layouts.cells.items():
            if template.maze is not None:
                raise ConfigError(
                    f"config key 'experiment.layouts.cells.{name}.maze': the layout sets give "
                    "each generated cell its maze; leave maze out of the template"
                )
        if not self.layouts.cells:
            raise ConfigError(
                "config key 'experiment.layouts.cells': no templates; name at least one "
                "(e.g. {ssrl: {method: ssrl}})"
            )
        if not self.layouts.sizes:
            raise ConfigError(
                "config key 'experiment.layouts.sizes': no layout sets; give at least one "
                "(e.g. {size: 5x5, obstacles: 9, count: 100})"
            )
        try:
            generated = expand([asdict(s) for s in self.layouts.sizes], list(self.layouts.cells))
        except LayoutSetError as exc:
            raise ConfigError(f"config key 'experiment.layouts.sizes.{exc.key}': {exc}") from None
        out = dict(self.cells)
        for name, g in generated.items():
            if name in out:
                raise ConfigError(
                    f"config key 'experiment.cells.{name}': the layout sets generate a cell of "
                    "that name; rename it"
                )
            out[name] = replace(self.layouts.cells[g.template], maze=g.maze)
        return out

    report: ReportSpec | None = None
    """How the report presents the experiment (``pipeline/report/spec.py``); none: the default section."""


@dataclass
class TrialsConfig:
    """``python -m pipeline trials``: independent runs of a method on a maze (or every cell of an
    experiment), every episode recorded to MCAP."""

    profile: Profile = field(default_factory=Profile)
    method: MethodSpec = field(default_factory=MethodSpec)
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``conf/recogniser/``): ``_target_`` and its arguments."""
    experiment: Experiment | None = None
    maze: str = setting(nonempty=True)
    """A built-in layout (``conf/mazes/<name>.txt``), a path to a layout file, or a generated layout
    ``random:<W>x<H>:<obstacles>:<seed>[:unique]`` (``pipeline/world/generate.py``)."""
    substitution: int = setting(choices=SUBSTITUTION_WAYS)
    """Dynamic support set: substitution way 1-4 (section 3.3); used by methods with dynamic_support."""
    support: str = setting(choices=SUPPORT_MODES)
    """``restore`` the support set before each run, or ``carry`` it over (long-term autonomy)."""
    images_dir: str | None = None
    """Rendered pictures (the render stage's folder) whose query pictures and initial support set the
    records keep, for recognisers without pictures of their own (oracle, fixed_accuracy); relation_net
    records those of its ``recogniser.images_dir``."""
    runs: int = setting(II("profile.trials.runs"), ge=1)
    episodes: int = setting(II("profile.trials.episodes"), ge=1)
    seed: int = setting(ge=0)
    out: str = setting(nonempty=True)
    overwrite: bool = MISSING
    """Replace results already in ``out``; without it such an ``out`` is refused (``dvc repro``
    deletes a stage's outs before running it, so there the ``out`` is empty)."""
    metrics_file: str | None = None
    timing_file: str | None = None
    record: str = setting(choices=RECORD_LEVELS)
    """What the MCAP records hold (docs/records.md "Record levels"): ``steps`` every step, ``episodes``
    per-episode summaries and every recognition, substitution and unsafe pair, ``none`` no record file."""
    flush_every: int = setting(ge=1)
    progress: bool = MISSING
    threads: int = setting(ge=0)
    """numba threads; 0 = all cores (divided among the ``workers``)."""
    workers: int = setting(1, ge=1)
    """Processes that run an experiment's cells side by side (each builds the recogniser once); the
    results are the same bytes for any number."""


# ---------------------------------------------------------------- render
@dataclass
class MazeCameraConfig:
    cell: float = setting(gt=0)
    camera_distance: float = setting(gt=0)
    camera_height: float = setting(gt=0)
    target_height: float = setting(gt=0)
    fovy: float = setting(gt=0, lt=180)


@dataclass
class CatalogueCameraConfig:
    fovy: float = setting(gt=0, lt=180)
    elevation: list[float] = MISSING
    turn: list[float] = MISSING
    fill: float = setting(gt=0, le=1)


@dataclass
class QualityConfig:
    offsamples: int = setting(ge=0)
    supersample: int = setting(ge=1)
    shadow_size: int = setting(ge=1)
    studio_shadows: bool = MISSING


@dataclass
class RenderConfig:
    profile: Profile = field(default_factory=Profile)
    out_dir: str = setting(nonempty=True)
    figures_dir: str = setting(nonempty=True)
    size: int = setting(ge=8)
    seed: int = setting(ge=0)
    workers: int = setting(II("profile.render.workers"), ge=1)
    categories: list[str] = MISSING
    n_train_classes: int = setting(II("profile.render.n_train_classes"), ge=0)
    n_val_classes: int = setting(II("profile.render.n_val_classes"), ge=0)
    per_class: int = setting(II("profile.render.per_class"), ge=1)
    views_per_instance: int = setting(ge=1)
    support_per_category: int = setting(ge=1)
    maze: MazeCameraConfig = field(default_factory=MazeCameraConfig)
    catalogue: CatalogueCameraConfig = field(default_factory=CatalogueCameraConfig)
    quality: QualityConfig = field(default_factory=QualityConfig)
    contact_sheets: bool = MISSING
    contact_tile: int = setting(ge=8)
    contact_train_classes: int = setting(ge=1)
    contact_per_class: int = setting(ge=1)


# ---------------------------------------------------------------- meta_train, accuracy
@dataclass
class DataConfig:
    """Where meta-training's classes come from (``conf/data/``): ``rendered``, the render stage's
    ``train`` and ``val`` splits in ``images_dir``; ``folder``, two folder-per-class trees
    (:func:`pipeline.fewshot.data.load_folder`), such as miniImageNet's."""

    source: str = setting(choices=DATA_SOURCES)
    train_dir: str | None = None
    """``data=folder``: the training classes, ``<train_dir>/<class>/<picture>``."""
    val_dir: str | None = None
    """``data=folder``: the validation classes (model selection and the reported accuracy)."""


@dataclass
class MetaTrainConfig:
    profile: Profile = field(default_factory=Profile)
    data: DataConfig = field(default_factory=DataConfig)
    images_dir: str = setting(nonempty=True)
    """``data=rendered``: the render stage's output, whose train and val splits are read."""
    checkpoint: str = setting(nonempty=True)
    metrics_file: str = setting(nonempty=True)
    history_file: str = setting(nonempty=True)
    threads: int = setting(ge=1)
    progress: bool = MISSING
    train: TrainConfig = field(default_factory=TrainConfig)


@dataclass
class AccuracyConfig:
    profile: Profile = field(default_factory=Profile)
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``conf/recogniser/``), as in the trials."""
    out_dir: str = setting(nonempty=True)
    threads: int = setting(ge=1)
    progress: bool = MISSING
    study: StudyConfig = field(default_factory=StudyConfig)


# ---------------------------------------------------------------- replay, report
@dataclass
class ReplayConfig:
    file: str = setting(nonempty=True)
    run: int = setting(ge=0)
    episode: int = setting(ge=0)
    whole_run: bool = MISSING
    out: str | None = None
    viewer: str = setting(choices=VIEWERS)
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
    profile: Profile = field(default_factory=Profile)
    runs_dir: str = setting(nonempty=True)
    accuracy_dir: str = setting(nonempty=True)
    model_metrics: str = setting(nonempty=True)
    protonet_accuracy_dir: str = setting(nonempty=True)
    """The Prototypical Network's accuracy study, shown beside the Relation Network's (Tables 1-2)."""
    protonet_metrics: str = setting(nonempty=True)
    """The Prototypical Network's validation metrics (meta_train model=protonet)."""
    contact_dir: str = setting(nonempty=True)
    out: str = setting(nonempty=True)
    allow_missing: bool = MISSING
    """Build without experiments or cells that have no complete records (listed at the top)."""


#: Stage name -> its schema (``conf/<stage>.yaml`` lists ``<stage>_schema`` first in its defaults).
SCHEMAS = {
    "trials": TrialsConfig,
    "render": RenderConfig,
    "meta_train": MetaTrainConfig,
    "accuracy": AccuracyConfig,
    "replay": ReplayConfig,
    "report": ReportConfig,
}


def register() -> None:
    cs = ConfigStore.instance()
    for stage, schema in SCHEMAS.items():
        cs.store(name=f"{stage}_schema", node=schema)


register()
