"""A config as the records keep it (the metadata record ``config``: its YAML and its JSON, keys
sorted; docs/records.md "The schema"), made from one piece per top-level key.

The cells of a study differ from each other in a key or two (the maze, the method): the trials
stage keeps the pieces of the keys they share and renders only the others, instead of the whole
config every cell (a YAML dump of the trials config costs about 4 ms; 2,100 cells).
The pieces joined are the text of the whole (tested).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml

Pieces = dict[str, tuple[str, str]]  # top-level key -> (its YAML, its JSON "key":value)


class ConfigText(NamedTuple):
    """The two texts of the ``config`` metadata record."""

    yaml: str
    json: str


def _plain(o: Any) -> Any:
    if isinstance(o, (np.generic, np.ndarray, set, frozenset, tuple)):
        return o.tolist() if hasattr(o, "tolist") else list(o)
    if isinstance(o, Path):
        return str(o)
    if type(o).__module__.startswith("omegaconf"):  # a container inside a dataclass config
        from omegaconf import OmegaConf

        return OmegaConf.to_container(o, resolve=True)
    raise TypeError(f"cannot record a {type(o).__name__} in the metadata (value {o!r})")


def to_json(obj: Any) -> str:
    """Configs (dicts, OmegaConf containers, numpy values) as compact, sorted JSON."""
    if type(obj).__module__.startswith("omegaconf"):
        from omegaconf import OmegaConf

        obj = OmegaConf.to_container(obj, resolve=True)
    return json.dumps(obj, default=_plain, sort_keys=True, separators=(",", ":"))


def pieces(config: Mapping) -> Pieces:
    """Each top-level key's YAML (libyaml's emitter, keys sorted) and JSON (``"key":value``)."""
    plain = json.loads(to_json(config))  # numpy values, paths and OmegaConf as JSON has them
    return {
        key: (
            yaml.dump({key: value}, Dumper=yaml.CSafeDumper, sort_keys=True),
            to_json({key: value})[1:-1],
        )
        for key, value in plain.items()
    }


def joined(parts: Pieces) -> ConfigText:
    """The texts of the config whose keys' pieces are ``parts``."""
    if not parts:
        return ConfigText(yaml.dump({}, Dumper=yaml.CSafeDumper), "{}")
    keys = sorted(parts)
    return ConfigText(
        "".join(parts[k][0] for k in keys), "{" + ",".join(parts[k][1] for k in keys) + "}"
    )


def config_text(config: Mapping | str) -> ConfigText:
    """The texts of a config: a mapping (or OmegaConf container), or its YAML or JSON text."""
    if isinstance(config, str):
        return ConfigText(config, to_json(yaml.safe_load(config)))
    return joined(pieces(config))
