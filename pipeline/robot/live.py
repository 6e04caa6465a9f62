"""Recognisers of live camera pictures for the robot (issue 30): ``live_scores(run, image, truth)``
returns one score per category for a picture the robot has just taken (:mod:`.env`).

``truth`` is the world's ground-truth category of the obstacle on the cell the picture looks at
(-1 for none). Only the oracle reads it: it is the upper bound of recognition (paper section 4,
no misrecognition), not a recogniser of pictures; a learned recogniser must ignore it.
"""

from __future__ import annotations

import hashlib

import numpy as np
import torch
from PIL import Image

from pipeline.fewshot.data import to_tensor
from pipeline.fewshot.training import embed_all
from pipeline.rl.oracle import OracleRecogniser
from pipeline.world.pictures import N_CATEGORIES


class LiveOracle(OracleRecogniser):
    """The oracle for live pictures: score 1 for the ground-truth category at the picture's cell."""

    def live_scores(self, run: int, image: np.ndarray, truth: int) -> np.ndarray:
        out = np.zeros(N_CATEGORIES, dtype=np.float32)
        if truth >= 0:
            out[int(truth)] = 1.0
        return out

    def learn_from_live(self, run: int, image: np.ndarray, category: int) -> int:
        return -1


class LiveRelation:
    """The Relation Network (paper section 3.2.1, eq. 2) on live pictures, around a loaded
    :class:`pipeline.fewshot.recogniser.RelationRecogniser` (its runs, support sets and table):
    the picture is resized to the checkpoint's input (bilinear, as ``fewshot.data.load_image``),
    normalised with its statistics, embedded, and scored against the run's current class states.

    The dynamic support set (section 3.3) substitutes the live picture: :meth:`learn_from_live`
    gives it a member code ``LIVE_CODE_BASE + `` 48 bits of its bytes' SHA-256 (the same picture
    is the same member everywhere, so the shared score columns stay right) and puts it at the
    position the substitution way chooses."""

    LIVE_CODE_BASE = 1 << 20

    def __init__(self, recogniser):
        if getattr(recogniser, "kind", "") != "relation_net":
            raise ValueError(
                "live pictures are scored by the Relation Network only (recogniser=relation_net)"
            )
        self.inner = recogniser
        self.substitution_way = recogniser.substitution_way
        self.carry_over = recogniser.carry_over
        self.size = recogniser.network.config.input_size
        norm = recogniser.checkpoint["normalisation"]
        self._mean, self._std = norm["mean"], norm["std"]

    def start_run(self, run: int, seed: int) -> None:
        self.inner.start_run(run, seed)

    def describe(self) -> dict:
        return {**self.inner.describe(), "live_pictures": True}

    @torch.no_grad()
    def _halves(self, image: np.ndarray):
        im = Image.fromarray(np.asarray(image, dtype=np.uint8))
        if im.size != (self.size, self.size):
            im = im.resize((self.size, self.size), Image.Resampling.BILINEAR)
        x = to_tensor(np.array(im)[None], self._mean, self._std)
        f = embed_all(self.inner.network, x, channels_last=False)
        class_half, query_half = self.inner.network.relation.first_conv_halves(f, f)
        return class_half[0], query_half[0]

    @torch.no_grad()
    def live_scores(self, run: int, image: np.ndarray, truth: int) -> np.ndarray:
        """Relation scores (C,) of the live picture; ``truth`` is not read."""
        _, query_half = self._halves(image)
        state = self.inner._run(run).state  # (C, ...) class halves with bias
        h = state + query_half.unsqueeze(0)
        return self.inner.network.relation.after_first_conv(h).numpy().reshape(-1)

    def learn_from_live(self, run: int, image: np.ndarray, category: int) -> int:
        """Substitute the live picture into ``category``'s support members; the position, or -1."""
        data = np.ascontiguousarray(image, dtype=np.uint8).tobytes()
        code = self.LIVE_CODE_BASE + int.from_bytes(hashlib.sha256(data).digest()[:6], "big")
        self.inner._part[code] = self._halves(image)[0]
        state = self.inner._run(run)
        pos = state.support.substitute(int(category), code)
        if pos >= 0:
            self.inner._refresh(state, int(category))
        return pos
