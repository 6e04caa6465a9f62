"""Few-shot reasoning-based safe RL for robot navigation: a reproducible pipeline.

``import pipeline`` registers the Gymnasium ids ``SafeNav-5x5-v0``, ``SafeNav-7x7-v0`` and
``SafeNav-11x11-v0`` (``pipeline.envs``) and ``SafeNav3D-<maze>-v0`` (the camera robot, ``pipeline.robot``) without importing Gymnasium itself: see
``pipeline.registration``. ``register_envs()`` registers them by hand.
"""

from pipeline.registration import ENV_IDS, ENV_IDS_3D, register_envs
from pipeline.registration import install as _install

__all__ = ["ENV_IDS", "ENV_IDS_3D", "register_envs"]

_install()
