"""What ``gymnasium.make("SafeNav3D-<maze>-v0", ...)`` calls: the robot environment
(:class:`pipeline.robot.env.SafeNavigation3DEnv`) with its recogniser of live pictures.

    gymnasium.make("SafeNav3D-5x5-v0", method="fewshot_dss", recogniser="relation_net",
                   render_mode="rgb_array")

``recogniser`` by name (any of ``pipeline/conf/recogniser/``, built as for ``SafeNav-*``:
:func:`pipeline.envs.recogniser_for`) or a recogniser object; the environment asks it about live
pictures (:func:`pipeline.robot.live.live`: the few-shot networks score the live picture, the
models of recognition answer as for the grid's query picture).
``render()`` is the maze from above and behind the robot; the camera's picture of a step is
``info["camera"]`` (None when the robot took none). ``info["cost"]`` is 1.0 on a collision;
:class:`pipeline.envs.SixValueStep` gives Safety-Gymnasium's six-value ``step``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pipeline.envs import recogniser_for
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.robot.env import SafeNavigation3DEnv
from pipeline.robot.world import DEFAULT_CELL


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
    timestep: float = 0.02,
    threshold: float = 0.5,
    registered_maze: str | None = None,
) -> SafeNavigation3DEnv:
    """The robot environment; ``registered_maze`` (the id's) refuses another ``maze``."""
    if registered_maze is not None:
        if maze is not None and maze != registered_maze:
            raise ValueError(
                f"maze={maze!r}: SafeNav3D-{registered_maze}-v0 is the {registered_maze} maze"
            )
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
        threshold=threshold,
    )


make_env3d.metadata = dict(SafeNavigation3DEnv.metadata)
