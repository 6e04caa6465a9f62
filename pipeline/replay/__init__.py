"""Rerun replay of the episode records (docs/replay.md; a robot cell's in 3D:
docs/robot3d.md "Replay"): what every world's replay shows (:mod:`.story`: recognitions, events,
support set, A_d), the grid's own views (:mod:`.draw`, :mod:`.panels`), the robot's scene in 3D
(:mod:`.robot3d`), and the recording built from a record file alone (:mod:`.build`).

``replay`` reads the files through :mod:`pipeline.records`; nothing in ``records`` imports it. It
sits beside ``robot`` (.importlinter): a robot cell's records are read for it by
:func:`pipeline.robot.replay.robot_run`, which the stage ``replay`` hands to :func:`build_replay`.
"""

from .build import ReplayError, build_replay, opening_episode, recording_name, replay_stem

__all__ = ["ReplayError", "build_replay", "opening_episode", "recording_name", "replay_stem"]
