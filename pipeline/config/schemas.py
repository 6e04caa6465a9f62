"""The typed schema of every stage's config (Hydra structured configs, registered in the ConfigStore).

``conf/<stage>.yaml`` names its schema first in its defaults list (``- trials_schema``) and gives the
values; the dataclasses give each key's type, range or choices and, in the string under it, its
description (:mod:`pipeline.schema`). Hydra refuses wrong types and unknown keys while composing;
:func:`pipeline.schema.check` refuses values out of range; ``python -m pipeline <stage> --help``
prints the same declarations (``pipeline/config/help.py``).

Each stage's schema lives in its own module, named in :data:`SCHEMA_OF` and imported only when
that stage composes its config: a stage loads the code its own config needs and no other's
(``scripts/dvc_deps.py`` derives each stage's code dependencies in dvc.yaml from those imports).
The trials' (:mod:`.trials`) types the ``method`` group by
:class:`~pipeline.rl.methods.MethodSpec` and ``experiment`` by
:class:`~pipeline.config.experiment.Experiment`; the few-shot stages' (:mod:`.fewshot`)
type ``data``; every stage types ``profile`` by :class:`~pipeline.config.profile.Profile`; a
recogniser is typed by the signature of its ``_target_`` (``pipeline.config.recognisers``). The
replay and report schemas, which import nothing of the package's science, are here.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from omegaconf import MISSING

from pipeline.schema import setting

VIEWERS = ("none", "web", "native")


@dataclass
class ReplayConfig:
    """``python -m pipeline replay``: one recorded episode (or a whole run) in Rerun."""

    file: str = setting(nonempty=True, path=True)
    """An ``.mcap`` record file (or the ``.mcap.partial`` of a killed run)."""
    run: int = setting(ge=0)
    """The run to replay."""
    episode: int | None = setting(None, ge=0)
    """The episode to replay; none: the run's first episode with a recognition."""
    whole_run: bool = MISSING
    """Every episode of the run on one timeline (refused together with ``episode``)."""
    out: str | None = setting(None, path=True)
    """The ``.rrd`` to write; none: ``replays/<experiment>-<cell>-run<run>-ep<episode>.rrd`` (``-all.rrd``
    with ``whole_run``), named from the record file's folders."""
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

    runs_dir: str = setting(nonempty=True, path=True)
    """The trials' records: ``<runs_dir>/<experiment>/<cell>/records.mcap``."""
    accuracy_dir: str = setting(nonempty=True, path=True)
    """The accuracy stage's data files (the Relation Network's)."""
    model_metrics: str = setting(nonempty=True, path=True)
    """The Relation Network's validation metrics (meta_train)."""
    protonet_accuracy_dir: str = setting(nonempty=True, path=True)
    """The Prototypical Network's accuracy study, shown beside the Relation Network's (Tables 1-2)."""
    protonet_metrics: str = setting(nonempty=True, path=True)
    """The Prototypical Network's validation metrics (meta_train model=protonet)."""
    contact_dir: str = setting(nonempty=True, path=True)
    """The render stage's contact sheets, copied to the report's figures."""
    out: str = setting(nonempty=True, path=True)
    """``index.md``, ``tables/`` and ``figures/`` (replaced only by a complete build)."""
    allow_missing: bool = MISSING
    """Build without experiments or cells that have no complete records (listed at the top)."""
    allow_mixed_scales: bool = MISSING
    """Build from cells recorded at different scales (profiles), each named at the top."""


#: Stage name -> its schema class as ``module:Class`` (``conf/<stage>.yaml`` lists
#: ``<stage>_schema`` first in its defaults).
SCHEMA_OF = {
    "trials": "pipeline.config.trials:TrialsConfig",
    "render": "pipeline.config.render:RenderConfig",
    "meta_train": "pipeline.config.fewshot:MetaTrainConfig",
    "accuracy": "pipeline.config.fewshot:AccuracyConfig",
    "replay": f"{__name__}:ReplayConfig",
    "report": f"{__name__}:ReportConfig",
}


def schema_of(stage: str) -> type:
    """The schema class of ``stage`` (its module imported now)."""
    module, name = SCHEMA_OF[stage].split(":")
    return getattr(importlib.import_module(module), name)


def schemas() -> dict[str, type]:
    """Every stage's schema class (importing every schema module)."""
    return {stage: schema_of(stage) for stage in SCHEMA_OF}


def register(stage: str) -> None:
    """Store ``stage``'s schema in Hydra's ConfigStore as ``<stage>_schema`` (before composing)."""
    from hydra.core.config_store import ConfigStore

    ConfigStore.instance().store(name=f"{stage}_schema", node=schema_of(stage))
