"""The trials stage's schema: :class:`TrialsConfig` (``conf/trials.yaml``), typing its
``method`` group by :class:`~pipeline.rl.methods.MethodSpec`, ``experiment`` by
:class:`~pipeline.schemas.experiment.Experiment` and ``profile`` by
:class:`~pipeline.schemas.profile.Profile` (the conventions: ``pipeline/schemas/__init__.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from omegaconf import MISSING

from pipeline.config.fields import setting
from pipeline.rl.methods import MethodSpec
from pipeline.schemas.experiment import (
    RULES,
    SUBSTITUTION_WAYS,
    SUPPORT_MODES,
    WORLDS,
    Experiment,
    RobotConfig,
)
from pipeline.schemas.profile import Profile, profile_key

RECORD_LEVELS = ("steps", "episodes", "none")


@dataclass
class TrialsConfig:
    """``python -m pipeline trials``: independent runs of a method on a maze (or every cell of an experiment), every episode recorded to MCAP."""

    #: Keys that say where the outputs go or how the run shows and spreads its work, not what it
    #: computes (the records are the same bytes for any value): dvc.yaml's params leave them out.
    OUTPUT_NEUTRAL: ClassVar[tuple[str, ...]] = (
        "out",
        "overwrite",
        "index_file",
        "metrics_dir",
        "timing_file",
        "progress",
        "threads",
        "workers",
        "hydra",
    )

    #: The keys ``--help`` shows first, in one screen (``--help-all``: every key of the schema).
    COMMON_KEYS: ClassVar[tuple[str, ...]] = (
        "maze",
        "world",
        "runs",
        "episodes",
        "seed",
        "substitution",
        "rule",
        "record",
        "out",
        "overwrite",
        "workers",
    )

    profile: Profile = field(default_factory=Profile)
    """The scale (``conf/profile/``): ``runs`` and ``episodes`` default to its ``trials`` keys."""
    method: MethodSpec = field(default_factory=MethodSpec)
    """The method (``conf/method/``): its file over the base method, then ``method.<field>=``."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """The recogniser group (``conf/recogniser/``): ``_target_`` and its arguments."""
    experiment: Experiment | None = None
    """An experiment (``+experiment=<name>``, ``conf/experiment/``): several cells, one run each."""
    maze: str = setting(nonempty=True, path=True)
    """A built-in layout (``conf/mazes/<name>.txt``), a path to a layout file, or a generated layout ``random:<W>x<H>:<obstacles>:<seed>[:unique]`` (``pipeline/world/generate.py``)."""
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
    images_dir: str | None = setting(None, path=True)
    """Rendered pictures (the render stage's folder) whose query pictures and initial support set the records keep, for recognisers without pictures of their own (oracle, fixed_accuracy); relation_net records those of its ``recogniser.images_dir``."""
    runs: int = profile_key("trials", "runs")
    episodes: int = profile_key("trials", "episodes")
    seed: int = setting(ge=0)
    """Seeds every run: run ``r`` draws its placement, exploration and recogniser from ``(seed, r)``."""
    out: str = setting(nonempty=True, path=True)
    """Writes ``<out>/summary.json`` (+ ``records.mcap``); an experiment: ``<out>/<cell>/``."""
    overwrite: bool = MISSING
    """Replace results already in ``out``; without it such an ``out`` is refused (dvc.yaml's trials stages give it: DVC keeps their outs, ``persist``)."""
    index_file: str | None = setting(None, path=True)
    """An experiment: every file of ``out`` with its SHA-256 (``pipeline.files.write_index``), for dvc.yaml."""
    metrics_dir: str | None = setting(None, path=True)
    """An experiment's DVC metrics go to this folder (replaced): one small file per cell, or per template and size over generated layouts (``pipeline/cells/metrics.py``)."""
    timing_file: str | None = setting(None, path=True)
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
