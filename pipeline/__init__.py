"""Few-shot reasoning-based safe RL for robot navigation: a reproducible pipeline.

``import pipeline`` registers the Gymnasium ids ``SafeNav-v0``, ``SafeNav-<maze>-v0``
(``pipeline.envs``) and ``SafeNav3D-<maze>-v0`` (the camera robot, ``pipeline.robot``) for the
mazes 5x5, 7x7 and 11x11: ``pipeline.registration``.
"""

from pipeline.registration import ENV_IDS, ENV_IDS_3D

__all__ = ["ENV_IDS", "ENV_IDS_3D"]
