"""What the trial runner hands to whoever records its episodes (DESIGN.md "Records").

The runner calls ``sink.episode(**fields)`` once per finished episode of every run, in run-major,
episode order per run (episodes of different runs may interleave), and ``sink.substitution(...)``
whenever a run's dynamic support set changed. ``rl`` does not import ``records``: the MCAP writer
implements this protocol, and so can anything else (a list in a test).

Episode fields (numpy arrays are 1-D, one entry per executed step unless stated):
    run, episode                 int
    states                       int32[T]   cell index ``row * width + col`` before the step
    actions                      int8[T]    0 N, 1 E, 2 S, 3 W (the executed action)
    rewards                      float32[T]
    flags                        uint8[T]   bit 0 RESELECTED (the first choice was unsafe/prevented
                                            and the agent reselected), bit 1 COLLIDED, bit 2 RECOVERED
                                            (self-recovery reverted the robot), bit 3 GOAL,
                                            bit 4 TRUNCATED (200-step limit)
    recognitions                 dict of arrays, one entry per picture seen:
        step int32, state int32, action int8, picture int16, predicted int8, true int8,
        scores float32[n, C] (or empty when the recogniser gives none)
    unsafe_added                 dict of arrays, one entry per (s, a) added to A_d:
        step int32, state int32, action int8, source int8 (0 recognition, 1 collision, 2 ssrl rule)
    summary                      dict: steps, collisions, return_, reached_goal, prevented,
                                 epsilon (at the end of the episode), greedy_optimal (the
                                 greedy policy walks an optimal path after this episode)
"""
from __future__ import annotations

from typing import Any, Protocol

FLAG_RESELECTED = 1
FLAG_COLLIDED = 2
FLAG_RECOVERED = 4
FLAG_GOAL = 8
FLAG_TRUNCATED = 16

SOURCE_RECOGNITION = 0
SOURCE_COLLISION = 1
SOURCE_SSRL_RULE = 2


class EpisodeSink(Protocol):
    def episode(self, **fields: Any) -> None: ...

    def substitution(self, *, run: int, episode: int, step: int, picture: int, category: int,
                     position: int) -> None: ...
