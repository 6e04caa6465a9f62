"""A recogniser of known accuracy, for controlled studies: how accurate must recognition be for
few-shot reasoning (paper section 3.2.2) to pay off?

At the start of a run each query picture is recognised correctly with probability ``p``, drawn once
per picture from the run's recogniser seed; a wrong picture is named as one of the other categories,
uniformly. With ``learn`` (the default), a picture that was substituted into the support set after a
collision (dynamic methods, section 3.3) is recognised correctly for the rest of the run: the
picture is now one of the shots of its category. With ``carry_over`` (long-term autonomy) a run
starts from what the previous run of its slot ended with.
"""

from __future__ import annotations

import numpy as np

from pipeline.rl.oracle import TRUE_CATEGORY
from pipeline.world.pictures import N_CATEGORIES, N_PICTURES

_ONE_HOT = np.eye(
    N_CATEGORIES, dtype=np.float32
)  # category -> its scores (a row per call is a copy)


class FixedAccuracyRecogniser:
    """``conf/recogniser/fixed_accuracy.yaml``: ``p`` in [0, 1], ``learn`` true/false."""

    display_name = "fixed accuracy"  # its name in the report (pipeline.report.names)
    reads_support = "nothing"  # no support positions: the substitution way changes nothing

    def __init__(
        self,
        p: float = 1.0,
        learn: bool = True,
        substitution_way: int = 0,
        carry_over: bool = False,
    ):
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"p must lie in [0, 1], got {p}")
        self.p, self.learn = float(p), bool(learn)
        self.substitution_way, self.carry_over = substitution_way, carry_over
        self._pred: dict[int, np.ndarray] = {}

    def start_run(self, run: int, seed: int) -> None:
        if self.carry_over and run in self._pred:
            return
        rng = np.random.default_rng(seed)
        right = rng.random(N_PICTURES) < self.p
        shift = rng.integers(1, N_CATEGORIES, size=N_PICTURES)
        self._pred[run] = np.where(
            right, TRUE_CATEGORY, (TRUE_CATEGORY + shift) % N_CATEGORIES
        ).astype(np.int8)

    def predictions(self, run: int) -> np.ndarray:
        return self._pred[run].copy()

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        """One-hot on the predicted category (this model has no relation scores)."""
        return _ONE_HOT[self._pred[run][np.asarray(picture_ids, dtype=np.int64)]]

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        """The picture joins the support set of its category: from now on it is recognised. There
        are no support positions in this model; 0 is returned (recorded as the position)."""
        if self.learn:
            self._pred[run][picture_id] = true_category
        return 0
