"""Recognisers of live camera pictures for the robot (issue 30): ``live_scores(run, image, truth)``
returns one score per category for a picture the robot has just taken (:mod:`.env`).

``truth`` is the world's ground-truth category of the obstacle on the cell the picture looks at
(-1 for none). Only the oracle reads it: it is the upper bound of recognition (paper section 4,
no misrecognition), not a recogniser of pictures; a learned recogniser must ignore it.
"""

from __future__ import annotations

import numpy as np

from pipeline.rl.oracle import OracleRecogniser
from pipeline.world.pictures import N_CATEGORIES


class LiveOracle(OracleRecogniser):
    """The oracle for live pictures: score 1 for the ground-truth category at the picture's cell."""

    def live_scores(self, run: int, image: np.ndarray, truth: int) -> np.ndarray:
        out = np.zeros(N_CATEGORIES, dtype=np.float32)
        if truth >= 0:
            out[int(truth)] = 1.0
        return out
