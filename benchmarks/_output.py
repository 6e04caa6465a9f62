"""Where every benchmark's figures go: one JSON file that names the command that made it."""

import json
import shlex
import sys
from pathlib import Path


def command(module: str) -> str:
    """The command line that is running ``module``, as a user would type it."""
    return shlex.join(["python", "-m", module, *sys.argv[1:]])


def write_figures(path: str | Path, figures: dict, module: str) -> Path:
    """``figures`` as JSON at ``path``, ``command`` (the command line that made them) first."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"command": command(module), **figures}, indent=2) + "\n")
    return path
