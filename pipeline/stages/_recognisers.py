"""Recognisers the stages can build besides the Relation Network (``pipeline.fewshot.recogniser``)."""
from __future__ import annotations

import numpy as np

from pipeline.world.pictures import N_CATEGORIES, N_PICTURES, picture_category


class OracleRecogniser:
    """Always names the true category: the upper bound of few-shot reasoning (no misrecognition)."""

    def start_run(self, run: int, seed: int) -> None:
        pass

    def predictions(self, run: int) -> np.ndarray:
        return np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        out = np.zeros((len(picture_ids), N_CATEGORIES), dtype=np.float32)
        out[np.arange(len(picture_ids)), [picture_category(int(p)) for p in picture_ids]] = 1.0
        return out

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        return -1
