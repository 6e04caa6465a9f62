"""The Gymnasium ids of the safe-navigation environment, registered by ``import pipeline`` with
plain ``register()`` calls, as Gymnasium's own ``gymnasium/envs/__init__.py`` registers its ids.

The entry points are strings, so registering imports neither the environment nor torch nor
``fewshot``: ``gymnasium.make`` imports ``pipeline.envs`` (or ``pipeline.envs3d``) when it builds
an environment. ``gymnasium.make("pipeline:SafeNav-5x5-v0")`` imports the package first
(Gymnasium's ``module:id`` form). Gymnasium 1.x reads no plugin entry points, so ``pyproject.toml``
declares none.
"""

from __future__ import annotations

from gymnasium.envs.registration import register

#: ``SafeNav-<maze>-v0`` for the built-in mazes (``conf/mazes/``), whose maze is fixed;
#: ``SafeNav-v0`` takes any maze by keyword (``gymnasium.make("SafeNav-v0", maze="random:7x7:16:3")``).
MAZES = ("5x5", "7x7", "11x11")
ENV_IDS = ("SafeNav-v0", *(f"SafeNav-{maze}-v0" for maze in MAZES))
#: ``SafeNav3D-<maze>-v0``: the same task with the camera robot in MuJoCo (``pipeline.robot``).
ENV_IDS_3D = tuple(f"SafeNav3D-{maze}-v0" for maze in MAZES)
ENTRY_POINT = "pipeline.envs:make_env"
ENTRY_POINT_3D = "pipeline.envs3d:make_env3d"
#: The method of the registered ids; other methods by keyword (``gymnasium.make(id, method=...)``).
DEFAULT_METHOD = "shield"
#: ``max_episode_steps`` of the ids: the default method's ``max_steps`` (``MethodSpec``; a test checks
#: it, so this module need not load the method configs).
MAX_EPISODE_STEPS = 200

register(
    id="SafeNav-v0",
    entry_point=ENTRY_POINT,
    max_episode_steps=MAX_EPISODE_STEPS,
    kwargs={"method": DEFAULT_METHOD},
)
for maze in MAZES:  # make_env and make_env3d refuse another maze= than the id's
    register(
        id=f"SafeNav-{maze}-v0",
        entry_point=ENTRY_POINT,
        max_episode_steps=MAX_EPISODE_STEPS,
        kwargs={"registered_maze": maze, "method": DEFAULT_METHOD},
    )
    register(
        id=f"SafeNav3D-{maze}-v0",
        entry_point=ENTRY_POINT_3D,
        max_episode_steps=MAX_EPISODE_STEPS,
        kwargs={"registered_maze": maze, "method": DEFAULT_METHOD},
    )
