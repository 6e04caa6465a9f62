"""The Hydra entry points, one per stage (``python -m pipeline <stage>``), and how each runs: compose
its typed config, run, and turn a user error into one line and exit status 2.

A stage is a module here with ``run(cfg, overrides)`` and a ``main()`` that calls
:func:`stage_main`; the first line of its docstring is its description (``--help``). Its config is
``conf/<stage>.yaml``, composed and checked by :func:`pipeline.config.compose.load_config`: any
:class:`~pipeline.errors.UserError` (a bad config, layout, checkpoint, image folder or record
file) prints ``error: <what>: <problem>`` on stderr and exits 2, before any work where it can be
detected up front. With ``-m`` (multirun sweeps) or Hydra's own flags (``--cfg``, ``--hydra-help``...)
the stage runs under ``hydra.main`` instead, so launchers (joblib, submitit) work; each job then
goes through the same conversion and error handling. ``--help`` (``-h``) prints the stage's groups
and keys from the schema (:mod:`pipeline.config.help`) without composing.

Every stage ends by printing one line on stdout naming what it wrote (``wrote <path>, <path>``):
its module's ``written(cfg, result)``, or, for a stage without one, the path its ``run`` returns.
:func:`run_stage` runs a stage in this process, as the command line would (tests, benchmarks and
notebooks use it).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from collections.abc import Callable
from contextlib import contextmanager
from typing import Any

from omegaconf import DictConfig

from pipeline.config.compose import load_config, sweep_points, typed
from pipeline.config.folder import conf_dir
from pipeline.config.help import FULL_HELP_FLAG, print_help, wants_help
from pipeline.errors import Interrupted, UserError

#: ``run(typed_config, overrides)``: the stage's work; ``overrides`` are the command line's.
Runner = Callable[[Any, list[str]], Any]


def fail(exc: UserError) -> None:
    print(f"error: {exc}", file=sys.stderr, flush=True)
    raise SystemExit(2) from None


#: Packages whose Python code runs numba's compiler: a signal there stops the process at once.
COMPILERS = ("numba", "llvmlite")


def in_compiler(frame) -> bool:
    """Whether ``frame`` (or a caller) is numba's or llvmlite's code: an exception raised there,
    as in a ctypes callback of LLVM, is swallowed or turned into another error."""
    roots = tuple(
        os.path.dirname(sys.modules[m].__file__) + os.sep for m in COMPILERS if m in sys.modules
    )
    while roots and frame is not None:
        if frame.f_code.co_filename.startswith(roots):
            return True
        frame = frame.f_back
    return False


def _stop(signum, frame, stop: BaseException) -> None:
    if in_compiler(frame):  # the first compile of a kernel: say so, and stop now
        print("interrupted while numba compiled a kernel", file=sys.stderr, flush=True)
        os._exit(128 + signum)
    raise stop


def _terminated(signum, frame) -> None:
    _stop(signum, frame, Interrupted(128 + signum))


def _keyboard(signum, frame) -> None:
    _stop(signum, frame, KeyboardInterrupt())


@contextmanager
def user_facing():
    """User errors as one line and exit 2; Ctrl-C and SIGTERM as one line (what was kept) and exit
    130 or 143, without a traceback."""
    previous = signal.signal(signal.SIGTERM, _terminated)
    keyboard = signal.signal(signal.SIGINT, _keyboard)
    try:
        yield
    except UserError as exc:
        fail(exc)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr, flush=True)
        raise SystemExit(130) from None
    except Interrupted as exc:
        print(exc.message, file=sys.stderr, flush=True)
        raise SystemExit(exc.code) from None
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, keyboard)


def _hydra_mode(args: list[str]) -> bool:
    return any(a.startswith("-") for a in args)


def wrote(stage: str, cfg: Any, result: Any) -> None:
    """Print the stage's last line: ``wrote`` and the folders and files it wrote."""
    module = importlib.import_module(f"pipeline.stages.{stage}")
    paths = module.written(cfg, result) if hasattr(module, "written") else [result]
    print("wrote " + ", ".join(str(p) for p in paths), flush=True)


def _run_and_say(stage: str, run: Runner, cfg: Any, overrides: list[str]) -> Any:
    result = run(cfg, overrides)
    wrote(stage, cfg, result)
    return result


def run_stage(stage: str, overrides: list[str] = ()) -> Any:
    """Run a stage in this process, as the command line would; a user error raises
    :class:`~pipeline.errors.UserError` (tests, benchmarks and notebooks use this)."""
    module = importlib.import_module(f"pipeline.stages.{stage}")
    return _run_and_say(stage, module.run, load_config(stage, overrides), list(overrides))


def stage_main(config_name: str, run: Runner, args: list[str] | None = None) -> Any:
    """Run a stage from the command line (``args``, default ``sys.argv[1:]``)."""
    args = list(sys.argv[1:] if args is None else args)
    if wants_help(args):
        return print_help(config_name, full=FULL_HELP_FLAG in args)
    if _hydra_mode(args):
        return _hydra_main(config_name, run, args)
    with user_facing():
        return _run_and_say(config_name, run, load_config(config_name, args), args)


def _hydra_main(config_name: str, run: Runner, args: list[str]) -> None:
    import hydra
    from hydra.core.hydra_config import HydraConfig

    from pipeline.config.registry import register

    register(config_name)
    if any(a in ("-m", "--multirun") for a in args):  # refuse a bad sweep before launching any job
        with user_facing():
            for point in sweep_points(args):
                load_config(config_name, point)

    @hydra.main(config_path=str(conf_dir()), config_name=config_name, version_base="1.3")
    def task(cfg: DictConfig) -> Any:
        with user_facing():
            return _run_and_say(
                config_name, run, typed(cfg), list(HydraConfig.get().overrides.task)
            )

    sys.argv = [sys.argv[0], *args]
    task()
