"""What the trial runner hands to whoever records its episodes (docs/records.md).

The runner calls ``sink.episodes(**batch)`` with a batch of consecutive finished episodes of one
run (columnar: the steps of all the batch's episodes concatenated, so a recorder encodes arrays,
not Python objects per episode), in episode order per run (batches of different runs may
interleave), and ``sink.substitution(...)`` whenever a run's dynamic support set changed. ``rl``
does not import ``records``: the MCAP writer implements this protocol, and so can anything else
(a list in a test; :func:`split_batch` gives one dict per episode). A sink whose attribute
``records_steps`` is False (the MCAP writer at ``record=episodes``) gets every field but the step rows
(``states``, ``actions``, ``rewards``, ``flags`` empty; ``steps`` still counts them): the runner then
keeps no step trace. Either way a run's episodes are handed over every ``EMIT_EVERY`` (500)
episodes, at the end, and, with steps, when the run's trace is full.

Batch fields (numpy arrays):
    run                          int
    episode                      int32[E]   episode indices (consecutive)
    steps                        int32[E]   executed steps of each episode (sum = T)
    states                       int32[T]   cell index ``row * width + col`` before the step
    actions                      int8[T]    0 N, 1 E, 2 S, 3 W (the executed action)
    rewards                      float32[T]
    flags                        uint8[T]   ``codes.StepFlag`` bits: reselected (the first choice
                                            was unsafe/prevented and the agent reselected), collided,
                                            recovered (self-recovery reverted the robot), goal,
                                            truncated (200-step limit)
    recognitions                 dict of arrays, one entry per picture seen:
        episode int32, step int32, state int32, action int8, picture int16, predicted int8,
        true int8, scores float32[n, C] (C = 0 when the recogniser gives none)
    unsafe_added                 dict of arrays, one entry per (s, a) added to A_d:
        episode int32, step int32, state int32, action int8, source int8 (a ``codes.Source``:
        recognition, collision, ssrl_rule)
    summary                      dict of arrays [E]: collisions int32, return_ float32,
                                 reached_goal bool, prevented int32, epsilon float32 (at the
                                 end of the episode), greedy_optimal bool (the greedy policy
                                 walks an optimal path after this episode)
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class EpisodeSink(Protocol):
    def episodes(self, **batch: Any) -> None: ...

    def substitution(
        self,
        *,
        run: int,
        episode: int,
        step: int,
        picture: int,
        category: int,
        position: int,
        support_accuracy: float,
    ) -> None:
        """The run's support set changed: ``picture`` entered ``category`` at ``position``; the
        support set now recognises ``support_accuracy`` of the query pictures. At the start of a
        run with a recogniser, one call with ``picture = position = -1`` gives the initial accuracy."""


def split_batch(batch: dict) -> list[dict]:
    """One dict per episode of a batch: run, episode, steps, states, actions, rewards, flags,
    recognitions, unsafe_added (each a dict of arrays) and summary (a dict of scalars)."""
    out = []
    ends = np.cumsum(batch["steps"])
    starts = ends - batch["steps"]
    rec, add, summ = batch["recognitions"], batch["unsafe_added"], batch["summary"]
    for i, ep in enumerate(batch["episode"]):
        sl = slice(int(starts[i]), int(ends[i]))
        rsel = rec["episode"] == ep
        asel = add["episode"] == ep
        out.append(
            {
                "run": int(batch["run"]),
                "episode": int(ep),
                "steps": int(batch["steps"][i]),
                "states": batch["states"][sl],
                "actions": batch["actions"][sl],
                "rewards": batch["rewards"][sl],
                "flags": batch["flags"][sl],
                "recognitions": {k: v[rsel] for k, v in rec.items()},
                "unsafe_added": {k: v[asel] for k, v in add.items()},
                "summary": {k: v[i].item() for k, v in summ.items()},
            }
        )
    return out
