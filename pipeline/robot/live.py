"""Any recogniser asked about the robot's live pictures (issue 30): the recogniser protocol of
``pipeline/rl/recogniser.py`` over the picture ids of a :class:`~.live_world.RobotWorld`, so the
one runner drives recognition, A_d, self-recovery and the dynamic support set as on the grid.

:func:`live` wraps a grid recogniser in one of two ways:

* a few-shot network (``relation_net``, ``protonet``: a
  :class:`~pipeline.fewshot.support_recogniser.SupportSetRecogniser`) scores the live pictures
  themselves. Each run gets the network over its own live pictures as the query set
  (``for_pictures``: the same weights, the same original support set), so the dynamic support set
  substitutes a live picture exactly as the grid substitutes a query picture (section 3.3), and the
  network never reads the world's categories.
* a model of recognition (``oracle``, ``fixed_accuracy``, ``paper_tables``, or any recogniser of
  the query pictures' ids) is not a recogniser of pixels: a live picture is answered as the model
  answers the query picture of the same side of the same obstacle (eq. 1), and self-recovery's
  substitution is the model's ``learn_from_collision`` of that query picture. With the paper's rule
  the robot then stops exactly where the grid does (tested).
"""

from __future__ import annotations

import numpy as np

from pipeline.fewshot.support_recogniser import SupportSetRecogniser
from pipeline.robot.live_world import RobotWorld


def live(recogniser, world: RobotWorld) -> LiveRecogniser:
    """The recogniser of ``world``'s live pictures around a grid recogniser."""
    missing = [
        name
        for name in ("start_run", "predictions", "scores", "learn_from_collision")
        if not callable(getattr(recogniser, name, None))
    ]
    if missing:
        raise ValueError(
            f"{type(recogniser).__name__} cannot recognise live pictures: it has no "
            f"{', '.join(missing)} (pipeline/rl/recogniser.py)"
        )
    if isinstance(recogniser, SupportSetRecogniser) and recogniser.checkpoint is None:
        raise ValueError("live pictures need a recogniser loaded from a checkpoint (from_files)")
    return LiveRecogniser(recogniser, world)


class LiveRecogniser:
    """The recogniser protocol over ``world``'s live pictures (module docstring). Run ``run``'s
    answers cover its own live pictures; every other id is answered -1 (no category)."""

    def __init__(self, inner, world: RobotWorld):
        self.inner, self.world = inner, world
        self.substitution_way = getattr(inner, "substitution_way", 0)
        self.carry_over = getattr(inner, "carry_over", False)
        self.network = isinstance(inner, SupportSetRecogniser)
        self._runs: dict[
            int, tuple[int, object]
        ] = {}  # run -> (first id, network over its pictures)

    def describe(self) -> dict | None:
        describe = getattr(self.inner, "describe", None)
        inner = describe() if describe is not None else None
        how = "scored" if self.network else "answered as the query picture of the same face"
        return {**(inner or {}), "live_pictures": how}

    def start_run(self, run: int, seed: int) -> None:
        first, got = self.world.run_pictures(run)
        own = None
        if self.network and len(got.pairs):
            own = self.inner.for_pictures(got.images, got.category)
            own.start_run(0, seed)
        elif not self.network:
            self.inner.start_run(run, seed)
        self._runs[run] = (first, own, got)

    def _local(self, run: int, ids) -> tuple[np.ndarray, object, object]:
        if run not in self._runs:
            raise KeyError(f"run {run} was not started; call start_run({run}, seed) first")
        first, own, got = self._runs[run]
        local = np.asarray(ids, np.int64) - first
        if local.size and (local.min() < 0 or local.max() >= len(got.pairs)):
            raise ValueError(f"run {run} sees live pictures {first}..{first + len(got.pairs) - 1}")
        return local, own, got

    def predictions(self, run: int) -> np.ndarray:
        self._local(run, [])  # a run that was not started is refused
        first, own, got = self._runs[run]
        out = np.full(self.world.n_pictures, -1, np.int8)
        if own is not None:
            out[first : first + len(got.pairs)] = own.predictions(0)
        elif not self.network and len(got.pairs):
            out[first : first + len(got.pairs)] = self.inner.predictions(run)[got.query]
        return out

    def scores(self, run: int, picture_ids) -> np.ndarray:
        local, own, got = self._local(run, picture_ids)
        if own is not None:
            return own.scores(0, local)
        if self.network:  # a run without live pictures
            return np.zeros((0, self.inner.n_way), np.float32)
        return np.asarray(self.inner.scores(run, got.query[local]))

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        """Self-recovery's reflection (section 3.3) on the live picture ``picture_id``: into the run's
        support set (networks), or the model's learning of the same face's query picture."""
        local, own, got = self._local(run, [picture_id])
        if own is not None:
            return own.learn_from_collision(0, int(local[0]), true_category)
        return int(self.inner.learn_from_collision(run, int(got.query[local[0]]), true_category))
