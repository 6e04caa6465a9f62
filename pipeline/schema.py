"""Constraints for the typed configs: ranges and choices declared once, on the dataclass field.

Hydra's structured configs check types and refuse unknown keys; they have no ranges. A field
declared with :func:`setting` carries its range or choices as metadata, and :func:`check` walks a
config object (dataclasses, dicts, lists) and refuses the first value out of range, naming its
full key. The science dataclasses (``MethodSpec``, ``TrainConfig``, ...) declare their fields this
way, so the schema is the only place a key is checked.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any

from omegaconf import MISSING

from pipeline.errors import ConfigError


def setting(
    default: Any = MISSING,
    *,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: Iterable[Any] | None = None,
    nonempty: bool = False,
    default_factory: Any = None,
):
    """A dataclass field with a range (``ge``/``gt``/``le``/``lt``), a set of ``choices`` or
    ``nonempty`` (strings), checked by :func:`check`."""
    meta = {
        k: v
        for k, v in {"ge": ge, "gt": gt, "le": le, "lt": lt, "nonempty": nonempty or None}.items()
        if v is not None
    }
    if choices is not None:
        meta["choices"] = tuple(choices)
    if default_factory is not None:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _problem(value: Any, meta: dict) -> str | None:
    if value is None:
        return None
    if "choices" in meta and value not in meta["choices"]:
        return f"must be one of {', '.join(map(str, meta['choices']))}; got {value!r}"
    if meta.get("nonempty") and not str(value).strip():
        return "must not be empty"
    for key, ok, word in (
        ("ge", lambda v, b: v >= b, ">="),
        ("gt", lambda v, b: v > b, ">"),
        ("le", lambda v, b: v <= b, "<="),
        ("lt", lambda v, b: v < b, "<"),
    ):
        if key in meta and not ok(value, meta[key]):
            return f"must be {word} {meta[key]}; got {value!r}"
    return None


def check(obj: Any, prefix: str = "") -> None:
    """Raise :class:`ConfigError` naming the first value of ``obj`` (recursively) that breaks its
    field's constraints."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        known = {f.name for f in dataclasses.fields(obj)}
        extra = sorted(
            k for k in vars(obj) if k not in known
        )  # added with '+key=' past Hydra's struct mode
        if extra:
            raise ConfigError(
                f"config key '{prefix}{extra[0]}': unknown key; known: {', '.join(sorted(known))}"
            )
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            key = f"{prefix}{f.name}"
            problem = _problem(value, f.metadata)
            if problem:
                raise ConfigError(f"config key '{key}': {problem}")
            check(value, key + ".")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            check(v, f"{prefix}{k}.")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            check(v, f"{prefix}{i}.")
