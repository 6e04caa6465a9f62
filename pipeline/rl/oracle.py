"""The oracle recogniser: always names the true category (the upper bound of few-shot reasoning:
Algorithm 1 with no misrecognition, so no collision with an obstacle it can see)."""

from __future__ import annotations

import numpy as np

from pipeline.world.pictures import N_CATEGORIES, N_PICTURES, picture_category

#: True category of every query picture id.
TRUE_CATEGORY = np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)


class OracleRecogniser:
    """``conf/recogniser/oracle.yaml``. The trial stage passes ``substitution_way`` and
    ``carry_over`` to every recogniser; an oracle has no support set to change."""

    reads_support = "nothing"  # the report's claims: no substitution way can change it

    def __init__(self, substitution_way: int = 0, carry_over: bool = False):
        self.substitution_way = substitution_way
        self.carry_over = carry_over

    def start_run(self, run: int, seed: int) -> None:
        pass

    def predictions(self, run: int) -> np.ndarray:
        return TRUE_CATEGORY.copy()

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        out = np.zeros((len(picture_ids), N_CATEGORIES), dtype=np.float32)
        out[np.arange(len(picture_ids)), TRUE_CATEGORY[np.asarray(picture_ids, dtype=np.int64)]] = (
            1.0
        )
        return out

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        return -1
