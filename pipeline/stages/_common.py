"""Helpers shared by the stage entry points (config validation, atomic JSON output)."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

#: Absolute path of the Hydra config folder: ``@hydra.main(config_path=CONF_DIR, ...)``.
#: (A relative ``config_path`` breaks when the stage is imported as a package module.)
CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")


class ConfigError(ValueError):
    """A configuration value that cannot work; the message names the key."""


def require(condition: bool, key: str, problem: str) -> None:
    if not condition:
        raise ConfigError(f"config key '{key}': {problem}")


def write_json_atomic(path: str | Path, data) -> Path:
    """Write JSON to a temporary file in the same folder, then rename: readers never see half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=2, sort_keys=False)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
