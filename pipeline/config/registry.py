"""The registry of the stages' schemas: which dataclass types ``conf/<stage>.yaml``
(:data:`SCHEMA_OF`), stored in Hydra's ConfigStore before composing (:func:`register`).

``conf/<stage>.yaml`` names its schema first in its defaults list (``- trials_schema``) and gives the
values; the dataclasses (:mod:`pipeline.schemas`) give each key's type, range or choices and, in the
string under it, its description (:mod:`pipeline.config.fields`). Hydra refuses wrong types and
unknown keys while composing; :func:`pipeline.config.fields.check` refuses values out of range;
``python -m pipeline <stage> --help`` prints the same declarations (:mod:`pipeline.config.help`).

Each stage's schema lives in its own module, named here and imported only when that stage composes
its config: a stage loads the code its own config needs and no other's (``scripts/dvc_deps.py``
derives each stage's code dependencies in dvc.yaml from those imports). The names are strings, so
this package, below the science packages, imports none of the schemas that type their pieces.
"""

from __future__ import annotations

import importlib

#: Stage name -> its schema class as ``module:Class`` (``conf/<stage>.yaml`` lists
#: ``<stage>_schema`` first in its defaults).
SCHEMA_OF = {
    "trials": "pipeline.schemas.trials:TrialsConfig",
    "render": "pipeline.schemas.render:RenderConfig",
    "meta_train": "pipeline.schemas.fewshot:MetaTrainConfig",
    "accuracy": "pipeline.schemas.fewshot:AccuracyConfig",
    "replay": "pipeline.schemas.replay:ReplayConfig",
    "report": "pipeline.schemas.report:ReportConfig",
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
