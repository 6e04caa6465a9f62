"""``safenav``: the installed command (``[project.scripts]`` in pyproject.toml), one name for the
project's command lines, each run by its own entry point:

* ``safenav <stage> [key=value ...]`` is ``python -m pipeline <stage> ...``
  (:func:`pipeline.__main__.main`: its stages, its ``--help``, its errors);
* ``safenav <tool> ...`` is ``python -m pipeline.<tool> ...`` for every package of ``pipeline``
  with a command line of its own (a ``__main__.py`` whose ``main(argv, prog)`` parses it):
  ``safenav records datasets/sample/fig8``.

This module parses nothing but the first word. It is not part of any stage's command (``python -m
pipeline`` never imports it), so DVC's code deps of the stages (dvc.yaml) do not list it.
"""

from __future__ import annotations

import ast
import importlib
import sys
from pathlib import Path

import pipeline
from pipeline.__main__ import available_stages, usage
from pipeline.__main__ import main as run_stage
from pipeline.errors import quiet_broken_pipe

PACKAGE_DIR = Path(pipeline.__file__).parent
HELP_FLAGS = ("-h", "--help")


def available_tools() -> list[str]:
    """The packages of ``pipeline`` with a ``__main__.py`` (``python -m pipeline.<tool>``)."""
    return sorted(p.parent.name for p in PACKAGE_DIR.glob("*/__main__.py"))


def summary(tool: str) -> str:
    """The first line of the tool's ``__main__`` docstring without the ``python -m
    pipeline.<tool>:`` in front (read from the source: no import, so ``--help`` stays fast)."""
    source = (PACKAGE_DIR / tool / "__main__.py").read_text()
    doc = (ast.get_docstring(ast.parse(source)) or "").strip()
    first = doc.splitlines()[0] if doc else ""
    return first.removeprefix(f"``python -m pipeline.{tool}``:").strip().replace("``", "")


def help_text(prog: str) -> str:
    """``python -m pipeline --help`` (its usage line and its stages) with ``prog`` for its name,
    then the tools. Its text is taken, not rewritten here, and not given a ``prog`` argument there:
    ``pipeline/__main__.py`` is a code dep of every DVC stage, and editing it reruns them all. A
    stage's own ``--help`` names the command it was run by (``pipeline.config.help.program``)."""
    tools = available_tools()
    stages_help = usage(available_stages()).replace("python -m pipeline", prog)
    width = max(map(len, tools)) + 2
    lines = [f"  {tool:<{width}}{summary(tool)}" for tool in tools]
    return "\n".join(
        [
            stages_help,
            "",
            "tools:",
            *lines,
            "",
            f"{prog} <tool> --help lists a tool's arguments.",
        ]
    )


def main(argv: list[str] | None = None, prog: str | None = None) -> None:
    """Run ``argv`` (default ``sys.argv[1:]``); ``prog`` is the command's name in help and errors
    (default: the name it was run by, ``safenav``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    prog = prog or Path(sys.argv[0]).name
    stages, tools = available_stages(), available_tools()
    if not argv or argv[0] in HELP_FLAGS:
        print(help_text(prog))
        raise SystemExit(0 if argv else 2)
    command, rest = argv[0], argv[1:]
    if command in tools:
        module = importlib.import_module(f"pipeline.{command}.__main__")
        return module.main(rest, prog=f"{prog} {command}")
    if command not in stages:
        print(
            f"error: unknown command {command!r}; stages: {', '.join(stages)}; "
            f"tools: {', '.join(tools)} ({prog} --help)",
            file=sys.stderr,
        )
        raise SystemExit(2)
    return run_stage(argv)


def console_script() -> None:
    """The entry point of ``safenav``: :func:`main`, ended quietly when its reader goes away."""
    with quiet_broken_pipe():
        main()
