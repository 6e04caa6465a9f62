"""What ``gymnasium.make("SafeNav3D-<maze>-v0", ...)`` calls: the robot environment
(:class:`pipeline.robot.env.SafeNavigation3DEnv`) with its recogniser of live pictures.

    gymnasium.make("SafeNav3D-5x5-v0", method="fewshot_dss", recogniser="relation_net",
                   render_mode="rgb_array")

``recogniser`` by name: ``oracle`` (:class:`~pipeline.robot.live.LiveOracle`) or ``relation_net``
(:class:`~pipeline.robot.live.LiveRelation` around the recogniser ``pipeline/conf/recogniser/
relation_net.yaml`` builds, as the trials stage builds it); or an object with ``live_scores``.
``render()`` is the maze from above and behind the robot; the camera's picture of a step is
``info["camera"]`` (None when the robot took none). ``info["cost"]`` is 1.0 on a collision;
:class:`pipeline.envs.SixValueStep` gives Safety-Gymnasium's six-value ``step``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pipeline.envs import make_recogniser
from pipeline.rl.methods import MethodSpec, get_method
from pipeline.robot.env import SafeNavigation3DEnv
from pipeline.robot.live import LiveOracle, LiveRelation
from pipeline.robot.world import DEFAULT_CELL

#: The recognisers of live pictures, by name.
LIVE_RECOGNISERS = ("oracle", "relation_net")


def live_recogniser(name: str, options: Mapping[str, Any] | None = None, substitution_way: int = 0):
    """A recogniser of live pictures by name (:data:`LIVE_RECOGNISERS`)."""
    if name == "oracle":
        if options:
            raise ValueError(f"recogniser 'oracle' takes no options, got {sorted(options)}")
        return LiveOracle(substitution_way=substitution_way)
    if name == "relation_net":
        return LiveRelation(make_recogniser(name, options, substitution_way=substitution_way))
    raise ValueError(
        f"recogniser {name!r} cannot score live camera pictures; the robot's are "
        f"{', '.join(LIVE_RECOGNISERS)}"
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
    if isinstance(recogniser, str):
        way = substitution if spec.dynamic_support else 0
        recogniser = (
            live_recogniser(recogniser, recogniser_options, way) if spec.uses_recogniser else None
        )
    elif recogniser_options:
        raise ValueError("recogniser_options go with a recogniser name (recogniser='relation_net')")
    return SafeNavigation3DEnv(
        "5x5" if maze is None else maze,
        spec,
        recogniser,
        run=run,
        render_mode=render_mode,
        cell=cell,
        timestep=timestep,
        threshold=threshold,
    )


make_env3d.metadata = dict(SafeNavigation3DEnv.metadata)
