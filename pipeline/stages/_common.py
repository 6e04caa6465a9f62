"""Helpers shared by the stage entry points (config validation, atomic JSON output)."""
from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

#: Absolute path of the Hydra config folder: ``@hydra.main(config_path=CONF_DIR, ...)``.
#: (A relative ``config_path`` breaks when the stage is imported as a package module.)
CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")


class ConfigError(ValueError):
    """A configuration value that cannot work; the message names the key."""


def check_keys(cfg: DictConfig, required: dict[str, type | tuple[type, ...]], stage: str) -> dict[str, Any]:
    """The config as a plain dict after checking that exactly ``required``'s top-level keys are
    present with the given types (``hydra`` excluded)."""
    plain = OmegaConf.to_container(cfg, resolve=True)
    plain.pop("hydra", None)
    plain.pop("profile", None)
    for key, kind in required.items():
        if key not in plain:
            raise ConfigError(f"{stage}: missing config key {key!r}")
        if not isinstance(plain[key], kind) or (kind is int and isinstance(plain[key], bool)):
            raise ConfigError(f"{stage}: config key {key!r} must be {kind}, got {plain[key]!r}")
    unknown = sorted(set(plain) - set(required))
    if unknown:
        raise ConfigError(f"{stage}: unknown config key(s) {unknown}; known: {sorted(required)}")
    return plain


def build(cls, values: dict[str, Any], prefix: str):
    """``cls(**values)`` (a dataclass) with errors naming ``prefix.key``."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise ConfigError(f"unknown config key(s) {[f'{prefix}.{k}' for k in unknown]}; known: {sorted(names)}")
    for f in dataclasses.fields(cls):
        if f.name in values and f.default is not dataclasses.MISSING:
            want = type(f.default)
            got = values[f.name]
            ok = isinstance(got, want) and not (want is int and isinstance(got, bool))
            if want is float and isinstance(got, int) and not isinstance(got, bool):
                ok, values[f.name] = True, float(got)
            if not ok:
                raise ConfigError(f"config key {prefix}.{f.name} must be {want.__name__}, got {got!r}")
    try:
        return cls(**values)
    except ValueError as exc:
        raise ConfigError(str(exc)) from exc


def require(condition: bool, key: str, problem: str) -> None:
    if not condition:
        raise ConfigError(f"config key '{key}': {problem}")


def write_json_atomic(path: str | Path, data, *, sort_keys: bool = False) -> Path:
    """Write JSON to a temporary file in the same folder, then rename: readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=2, sort_keys=sort_keys)
            f.write("\n")
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # mkstemp makes 0600 files
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
