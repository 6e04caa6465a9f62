"""The Gymnasium ids of the safe-navigation environment, registered by ``import pipeline``.

Only the standard library is imported here: ``import pipeline`` runs this module, every stage and
worker imports ``pipeline``, and importing Gymnasium (with numpy) would slow each of them. So the
ids are registered when Gymnasium is imported anyway: at once if it already is, otherwise by a
one-shot finder on ``sys.meta_path`` that lets the normal finders load
``gymnasium.envs.registration`` and registers right after that module has run, then removes itself. The entry points are strings, so
registering imports neither the environment nor torch nor ``fewshot``; ``gymnasium.make`` imports
``pipeline.envs`` when it builds an environment.

Gymnasium 1.x has no plugin entry points (``load_plugin_envs`` and the ``gymnasium.envs`` entry
point group were removed in 1.0), so ``pyproject.toml`` declares none; without ``import pipeline``,
``gymnasium.make("pipeline:SafeNav-5x5-v0")`` imports the package first (Gymnasium's
``module:id`` form) and works the same.
"""

from __future__ import annotations

import sys

#: ``SafeNav-<maze>-v0`` for the built-in mazes (``conf/mazes/``), whose maze is fixed;
#: ``SafeNav-v0`` takes any maze by keyword (``gymnasium.make("SafeNav-v0", maze="random:7x7:16:3")``).
MAZES = ("5x5", "7x7", "11x11")
ENV_IDS = ("SafeNav-v0", *(f"SafeNav-{maze}-v0" for maze in MAZES))
#: ``SafeNav3D-<maze>-v0``: the same task with the camera robot in MuJoCo (``pipeline.robot``).
ENV_IDS_3D = tuple(f"SafeNav3D-{maze}-v0" for maze in MAZES)
ENTRY_POINT_3D = "pipeline.envs3d:make_env3d"
#: The method of the registered ids; other methods by keyword (``gymnasium.make(id, method=...)``).
DEFAULT_METHOD = "shield"
#: ``max_episode_steps`` of the ids: the default method's ``max_steps`` (``MethodSpec``; a test checks
#: it, so this module need not load the method configs).
MAX_EPISODE_STEPS = 200
ENTRY_POINT = "pipeline.envs:make_env"
_REGISTRATION = "gymnasium.envs.registration"


def register_envs(registration=None) -> None:
    """Register the ids (each once; an id already in the registry is left as it is).
    ``registration`` is the ``gymnasium.envs.registration`` module (imported when not given)."""
    if registration is None:
        from gymnasium.envs import registration
    for env_id, maze in zip(ENV_IDS, (None, *MAZES)):
        if env_id not in registration.registry:
            fixed = {"registered_maze": maze} if maze else {}  # make_env refuses another maze=
            registration.register(
                id=env_id,
                entry_point=ENTRY_POINT,
                max_episode_steps=MAX_EPISODE_STEPS,
                kwargs={**fixed, "method": DEFAULT_METHOD},
            )
    for env_id, maze in zip(ENV_IDS_3D, MAZES):
        if env_id not in registration.registry:
            registration.register(
                id=env_id,
                entry_point=ENTRY_POINT_3D,
                max_episode_steps=MAX_EPISODE_STEPS,
                kwargs={"registered_maze": maze, "method": DEFAULT_METHOD},
            )


class _RegisterWhenGymnasiumLoads:
    """A ``sys.meta_path`` finder that finds nothing itself: for ``gymnasium.envs.registration``
    it asks the other finders for the spec and wraps that spec's loader so the ids are registered
    once the module has been executed."""

    def find_spec(self, name, path=None, target=None):
        if name != _REGISTRATION:
            return None
        for finder in list(sys.meta_path):
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                break
        else:
            return None
        loader = spec.loader
        load = getattr(loader, "exec_module", None)
        if load is None:
            return spec

        def exec_module(module):
            load(module)
            _uninstall()
            try:
                register_envs(module)
            except Exception as exc:  # noqa: BLE001 - never break ``import gymnasium`` for our ids
                import warnings

                warnings.warn(
                    f"pipeline could not register its Gymnasium ids ({exc!r}); "
                    "call pipeline.register_envs() to see why",
                    stacklevel=2,
                )

        try:
            loader.exec_module = exec_module  # on this loader object only; its class is untouched
        except (
            AttributeError
        ):  # a loader that takes no attributes: ``pipeline.register_envs()`` by hand
            pass
        return spec


def _uninstall() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _RegisterWhenGymnasiumLoads)]


def install() -> None:
    """Register now if Gymnasium's registry is loaded, else when it loads."""
    registration = sys.modules.get(_REGISTRATION)
    if registration is not None and hasattr(registration, "registry"):
        register_envs(registration)
    elif not any(isinstance(f, _RegisterWhenGymnasiumLoads) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())
