"""``python -m pipeline <stage> [hydra overrides...]``: one thin Hydra entry point per stage.

Each stage lives in ``pipeline/stages/<stage>.py`` with a ``main()`` that composes
``conf/<stage>.yaml`` (:func:`pipeline.stages.stage_main`); the first line of its docstring is the
description ``--help`` lists. ``<stage> --help`` prints the stage's groups and keys from the schema
(``pipeline/config/help.py``) without importing the stage's module.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import pipeline.stages as _stages
from pipeline.config.help import FULL_HELP_FLAG, describe, print_help, wants_help
from pipeline.errors import quiet_broken_pipe


def available_stages() -> list[str]:
    return sorted(
        m.name for m in pkgutil.iter_modules(_stages.__path__) if not m.name.startswith("_")
    )


def usage(stages: list[str]) -> str:
    """The top-level help: the stages, one line each."""
    width = max(len(s) for s in stages) + 2
    lines = [f"  {s:<{width}}{describe(s)}" for s in stages]
    return "\n".join(
        [
            "usage: python -m pipeline <stage> [key=value ...]",
            "",
            "stages:",
            *lines,
            "",
            "python -m pipeline <stage> --help lists a stage's config groups and keys.",
        ]
    )


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    stages = available_stages()
    if not argv or argv[0] in ("-h", "--help"):
        print(usage(stages))
        raise SystemExit(0 if argv else 2)
    stage = argv.pop(0)
    if stage not in stages:
        print(
            f"error: unknown stage {stage!r}; available stages: {', '.join(stages)}",
            file=sys.stderr,
        )
        raise SystemExit(2)
    if wants_help(argv):
        print_help(stage, full=FULL_HELP_FLAG in argv)
        raise SystemExit(0)
    module = importlib.import_module(f"pipeline.stages.{stage}")
    sys.argv = [f"pipeline {stage}", *argv]
    module.main()


if __name__ == "__main__":
    with quiet_broken_pipe():
        main()
