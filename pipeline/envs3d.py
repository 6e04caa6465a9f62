"""What ``gymnasium.make("SafeNav3D-<maze>-v0", ...)`` calls: the robot environment
(:class:`pipeline.robot.env.SafeNavigation3DEnv`, whose docstring tells its observations by
``obs_type``, its ``info`` and ``render()``) with its recogniser of live pictures::

    gymnasium.make("SafeNav3D-5x5-v0", method="fewshot_dss", recogniser="relation_net",
                   render_mode="rgb_array")
    gymnasium.make("SafeNav3D-5x5-v0", obs_type="pixels")   # the camera's picture, every step

``recogniser`` by name (any of ``conf/recogniser/``, built as for ``SafeNav-*``:
:func:`pipeline.envs.recogniser_for`) or a recogniser object; the environment asks it about live
pictures (:func:`pipeline.robot.live.live`: the few-shot networks score the live picture, the
models of recognition answer as for the grid's query picture).
:class:`pipeline.envs.SixValueStep` gives Safety-Gymnasium's six-value ``step``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pipeline.envs import human_rendering, recogniser_for, refuse_another_maze
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.robot.env import SafeNavigation3DEnv
from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP


@human_rendering(
    SafeNavigation3DEnv,
    instead="render_mode='rgb_array' (frames from env.render())",
    needs_display=True,
)
def make_env3d(
    maze: str | None = None,
    method: str | MethodSpec = "shield",
    recogniser=None,
    *,
    recogniser_options: Mapping[str, Any] | None = None,
    substitution: int = 1,
    run: int = 0,
    render_mode: str | None = None,
    cell: float = DEFAULT_CELL,
    timestep: float = DEFAULT_TIMESTEP,
    rule: str = "paper",
    threshold: float = 0.5,
    obs_type: str = "state",
    registered_maze: str | None = None,
) -> SafeNavigation3DEnv:
    """The robot environment; ``registered_maze`` (the id's) refuses another ``maze``
    (:func:`pipeline.envs.refuse_another_maze`). ``render_mode="human"``:
    :func:`pipeline.envs.human_rendering` (it needs pygame and a display)."""
    if registered_maze is not None:
        refuse_another_maze(maze, registered_maze, f"SafeNav3D-{registered_maze}-v0")
        maze = registered_maze
    spec = method if isinstance(method, MethodSpec) else get_method(method)
    return SafeNavigation3DEnv(  # it asks any recogniser about live pictures (robot.live.live)
        "5x5" if maze is None else maze,
        spec,
        recogniser_for(spec, recogniser, recogniser_options, substitution),
        run=run,
        render_mode=render_mode,
        cell=cell,
        timestep=timestep,
        rule=rule,
        threshold=threshold,
        obs_type=obs_type,
    )
