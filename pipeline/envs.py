"""What ``gymnasium.make("SafeNav-<maze>-v0", ...)`` calls: the environment with its recogniser.

``make_env`` is the entry point of the registered ids (``pipeline.registration``). It takes the
keywords of :class:`pipeline.rl.gym_env.SafeNavigationEnv`, and the recogniser also by name::

    gymnasium.make("SafeNav-5x5-v0", method="fewshot_dss", recogniser="oracle")
    gymnasium.make("SafeNav-7x7-v0", method="fewshot", recogniser="fixed_accuracy",
                   recogniser_options={"p": 0.8}, render_mode="rgb_array")

Why here: the environment lives in ``rl``, which never imports ``fewshot`` (the science
packages stay independent; README "Layout"), and a recogniser by name may be the Relation Network
of ``fewshot``. This module is wiring like the stages: its resolver, ``make_recogniser``, loads
``conf/recogniser/<name>.yaml`` and hands it to the trials stage's builder,
:func:`pipeline.config.recognisers.build_recogniser` (its ``_target_`` and the argument check
against the target's signature), so both build a recogniser through one path and the ``rl``
environment only ever receives an object. Nothing here is imported by ``import pipeline``.

Relative paths in a yaml (``relation_net``: ``datasets/...``) are read from the working directory,
as in the stages: run from the project root or pass absolute paths in ``recogniser_options``.
"""

from __future__ import annotations

import functools
import importlib.util
import numbers
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from pipeline.config.fields import refuse_argument
from pipeline.config.recognisers import RECOGNISER_DIR, build_recogniser, recogniser_names
from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.rl.recogniser import Recogniser
from pipeline.schemas.experiment import SUBSTITUTION_WAYS
from pipeline.threads import TORCH_THREADS_BESIDE_NUMBA, ThreadBudget
from pipeline.world.maze import Layout


def _check_name(name: str) -> Path:
    path = RECOGNISER_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ValueError(
            f"unknown recogniser {name!r}; expected one of {', '.join(recogniser_names())} "
            f"(conf/recogniser/<name>.yaml), or a Recogniser object"
        )
    return path


def make_recogniser(
    name: str,
    options: Mapping[str, Any] | None = None,
    *,
    substitution_way: int = 0,
    carry_over: bool = False,
) -> Recogniser:
    """The recogniser ``conf/recogniser/<name>.yaml``, with ``options`` overriding its keys, built
    as the trials stage builds it. Bad names and values raise ``ValueError`` (``ConfigError``).
    A recogniser that scores with torch leaves torch on one thread (:mod:`pipeline.threads`)."""
    node = OmegaConf.to_container(OmegaConf.load(_check_name(name)), resolve=True)
    node.update(dict(options or {}))
    recogniser = build_recogniser(node, substitution_way=substitution_way, carry_over=carry_over)
    # torch's share beside the rules' numba code, as in the trials stage (pipeline.threads)
    ThreadBudget(1, None, TORCH_THREADS_BESIDE_NUMBA).apply()
    return recogniser


def recogniser_for(
    spec: MethodSpec,
    recogniser: Recogniser | str | None,
    options: Mapping[str, Any] | None,
    substitution: int,
) -> Recogniser | None:
    """The recogniser an environment of method ``spec`` runs with: a name of
    ``conf/recogniser/`` is built (with ``options`` over its keys) only for a method that
    reasons with pictures, like the trials stage, with substitution way ``substitution`` for
    ``fewshot_dss``; an object is used as it is; ``options`` without a name are refused. A
    ``substitution`` other than 1-4 is refused whatever the method and recogniser, as the trials
    stage's schema refuses it."""
    if (
        isinstance(substitution, bool)
        or not isinstance(substitution, numbers.Integral)
        or substitution not in SUBSTITUTION_WAYS
    ):
        refuse_argument(
            "substitution",
            substitution,
            "the substitution way of the dynamic support set must "
            f"be one of {', '.join(map(str, SUBSTITUTION_WAYS))} (paper section 3.3)",
        )
    if isinstance(recogniser, str):
        if not spec.uses_recogniser:
            _check_name(recogniser)  # built for no method, but a wrong name is refused all the same
            return None
        way = substitution if spec.dynamic_support else 0
        return make_recogniser(recogniser, options, substitution_way=way)
    if options:
        raise ValueError(
            "recogniser_options go with a recogniser name (recogniser='fixed_accuracy', ...)"
        )
    return recogniser


def human_rendering(env_class: type, instead: str, needs_display: bool = False) -> Callable:
    """An environment factory that also takes ``render_mode="human"``: the factory's ``rgb_array``
    environment shown in a window by Gymnasium's ``HumanRendering``. What a window needs is checked
    at once (not at the first ``render()``): pygame, and a display if ``needs_display``; without
    them ``render_mode="human"`` is refused, naming ``instead`` (the render modes to use).
    ``gymnasium.make`` reads the render modes from the entry point, so the factory lists
    ``env_class``'s and ``human``, which then reaches it."""

    def refuse_without_window() -> None:
        if importlib.util.find_spec("pygame") is None:
            raise ValueError(
                "render_mode='human' opens a window through pygame, which is not installed "
                f"(pip install pygame); or use {instead}"
            )
        if needs_display and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise ValueError(
                "render_mode='human' needs a display (DISPLAY is not set); use render_mode='rgb_array'"
            )

    def decorate(make: Callable) -> Callable:
        @functools.wraps(make)
        def make_with_window(*args, render_mode: str | None = None, **kwargs):
            if render_mode != "human":
                return make(*args, render_mode=render_mode, **kwargs)
            refuse_without_window()
            from gymnasium.wrappers import HumanRendering

            return HumanRendering(make(*args, render_mode="rgb_array", **kwargs))

        modes = env_class.metadata["render_modes"]
        make_with_window.metadata = {**env_class.metadata, "render_modes": [*modes, "human"]}
        return make_with_window

    return decorate


def refuse_another_maze(
    asked: str | Layout | None, registered_maze: str, env_id: str, any_maze_id: str | None = None
) -> None:
    """An id names the maze it runs: ``registered_maze`` (the id's, ``SafeNav-7x7-v0``) refuses
    another ``asked`` maze, naming ``any_maze_id`` (``SafeNav-v0``, which takes any) if there is one."""
    if asked is None or asked == registered_maze:
        return
    message = f"maze={asked!r}: {env_id} is the {registered_maze} maze"
    if any_maze_id is not None:
        message += f"; for another maze use gymnasium.make({any_maze_id!r}, maze={asked!r})"
    raise ValueError(message)


@human_rendering(SafeNavigationEnv, instead="render_mode='rgb_array' (frames) or 'ansi' (text)")
def make_env(
    maze: str | Layout | None = None,
    method: str | MethodSpec = "shield",
    recogniser: Recogniser | str | None = None,
    *,
    recogniser_options: Mapping[str, Any] | None = None,
    substitution: int = 1,
    run: int = 0,
    render_mode: str | None = None,
    tile_size: int = 32,
    registered_maze: str | None = None,
) -> SafeNavigationEnv:
    """A :class:`SafeNavigationEnv`; ``recogniser`` an object or a name of ``conf/recogniser/``,
    built with ``recogniser_options`` and ``substitution`` (1-4, section 3.3) as
    :func:`recogniser_for` says. Each ``reset(seed=...)`` restores its support set.
    ``registered_maze``: the maze of the id (:func:`refuse_another_maze`; ``SafeNav-v0`` takes
    any, ``maze`` defaults to 5x5). ``render_mode="human"``: :func:`human_rendering`."""
    if registered_maze is not None:
        asked = getattr(maze, "name", maze)
        refuse_another_maze(asked, registered_maze, f"SafeNav-{registered_maze}-v0", "SafeNav-v0")
        maze = registered_maze
    spec = method if isinstance(method, MethodSpec) else get_method(method)
    recogniser = recogniser_for(spec, recogniser, recogniser_options, substitution)
    if recogniser is None and spec.uses_recogniser:
        raise ValueError(
            f"method {spec.name!r} reasons with pictures and needs a recogniser: pass "
            "recogniser=<name> with a name of conf/recogniser/ "
            f"({', '.join(recogniser_names())}), "
            f"e.g. gymnasium.make('SafeNav-5x5-v0', method={spec.name!r}, recogniser='oracle'), "
            f"or a Recogniser object (pipeline.rl.recogniser)"
        )
    return SafeNavigationEnv(
        "5x5" if maze is None else maze,
        spec,
        recogniser,
        run=run,
        render_mode=render_mode,
        tile_size=tile_size,
    )


class SixValueStep:
    """Safety-Gymnasium's ``step`` for the grid and the robot environments alike: ``(observation,
    reward, cost, terminated, truncated, info)``, with ``cost`` 1.0 on a collision and 0.0
    otherwise (``info["cost"]`` where the environment gives it, else ``info["collided"]``). Every
    other call goes to the wrapped environment::

        env = SixValueStep(gymnasium.make("SafeNav3D-5x5-v0"))
        obs, info = env.reset(seed=0)
        obs, reward, cost, terminated, truncated, info = env.step(1)
    """

    def __init__(self, env):
        self.env = env

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        cost = float(info.get("cost", 1.0 if info.get("collided") else 0.0))
        return obs, reward, cost, terminated, truncated, info

    def __getattr__(self, name):
        return getattr(self.env, name)
