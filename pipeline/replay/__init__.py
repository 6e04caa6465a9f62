"""Rerun replay of the episode records (docs/records.md "Replay it in Rerun"): what the viewer
shows (:mod:`.panels`) and the recording built from a record file alone (:mod:`.build`).

``replay`` reads the files through :mod:`pipeline.records`; nothing in ``records`` imports it.
"""

from .build import ReplayError, build_replay, opening_episode, recording_name, replay_stem

__all__ = ["ReplayError", "build_replay", "opening_episode", "recording_name", "replay_stem"]
