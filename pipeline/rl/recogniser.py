"""The recogniser as the RL loop sees it (paper section 3.2.1, eq. 2).

``rl`` never imports ``fewshot`` (``world``, ``fewshot`` and ``records`` import none of each other;
README "Layout"): any object with these methods drives Algorithm 1. The Relation
Network recogniser with its dynamic support set (``pipeline.fewshot``) implements it; the tests
use small deterministic recognisers.

Each independent run owns its support set, so every call names the run. Predictions are
deterministic for a given support set, which lets the trial runner look them up in a table and
ask again only after the support set changed (a substitution after a collision).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Recogniser(Protocol):
    def start_run(self, run: int, seed: int) -> None:
        """Prepare run ``run``'s support set (restored to the original, or carried over for
        long-term autonomy) and its substitution random stream, seeded by ``seed``."""

    def predictions(self, run: int) -> np.ndarray:
        """Predicted category (int) for every query picture id (length ``N_PICTURES``) under
        run ``run``'s current support set."""

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        """Relation scores, shape ``(len(picture_ids), n_categories)``, under the current support set."""

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        """Self-recovery's reflection (section 3.3): substitute the picture into the support set
        of ``true_category``; return the replaced position (0..K-1), or -1 when the support set
        is static."""
