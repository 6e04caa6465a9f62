"""Recognisers of the robot's live camera pictures (issue 30): every recogniser of the grid, by
name, asked about what the robot's camera sees (:mod:`.env`).

When the robot heads toward an occupied neighbour it takes a picture and asks
``live_scores(run, view) -> (n_categories,)``; after a collision, dynamic methods call
``learn_from_live(run, view) -> position`` (the support-set position replaced, or -1). A
:class:`LiveView` holds what there is to know about that moment. :func:`live` wraps a grid
recogniser into one of two kinds:

* :class:`LiveSupportSet` (``relation_net``, ``protonet``): the network scores the live picture
  itself against the run's current support set, and the dynamic support set (section 3.3)
  substitutes the live picture. Neither reads ``view.truth`` nor ``view.picture``.
* :class:`LiveByPicture` (``oracle``, ``fixed_accuracy``, ``paper_tables``, or any recogniser of
  query-picture ids): these are models of recognition, not recognisers of pixels. The robot's
  picture is answered as the grid answers the query picture of the same obstacle's side
  (``view.picture``, eq. 1): recognised when the model names the obstacle's category
  (``view.truth``), as the grid's rule compares them. A recognised picture scores 1 on its
  category, another 0 everywhere, so the robot's rule (top score at least ``robot.threshold``)
  stops exactly where the grid's prevents. Self-recovery's substitution is the model's
  ``learn_from_collision`` of that query picture. The oracle is thus the upper bound of
  recognition (section 4, no misrecognition), and ``fixed_accuracy`` with ``p`` recognises a
  side with probability ``p``, drawn once per run as on the grid.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
import torch
from PIL import Image

from pipeline.fewshot.data import to_tensor
from pipeline.fewshot.support_recogniser import SupportSetRecogniser
from pipeline.rl.oracle import TRUE_CATEGORY
from pipeline.world.pictures import N_CATEGORIES


@dataclass(frozen=True)
class LiveView:
    """The robot at a cell centre, facing an occupied neighbour."""

    image: np.ndarray  # (H, W, 3) uint8: its camera's picture, taken where it stands
    truth: int  # the world's category on that cell (-1 none): read by models, never by networks
    picture: int  # the query picture of the side it faces (-1 none): read by models only


def live(recogniser) -> LiveSupportSet | LiveByPicture:
    """The live-picture recogniser around a grid recogniser (one already live is returned)."""
    if isinstance(recogniser, (LiveSupportSet, LiveByPicture)):
        return recogniser
    if isinstance(recogniser, SupportSetRecogniser):
        return LiveSupportSet(recogniser)
    missing = [
        name
        for name in ("start_run", "predictions", "learn_from_collision")
        if not callable(getattr(recogniser, name, None))
    ]
    if missing:
        raise ValueError(
            f"{type(recogniser).__name__} cannot recognise live pictures: it has no "
            f"{', '.join(missing)} (pipeline/rl/recogniser.py)"
        )
    return LiveByPicture(recogniser)


class LiveByPicture:
    """A model of recognition on the robot: a live picture is answered as its query picture."""

    def __init__(self, recogniser):
        self.inner = recogniser
        self.substitution_way = getattr(recogniser, "substitution_way", 0)
        self.carry_over = getattr(recogniser, "carry_over", False)

    def start_run(self, run: int, seed: int) -> None:
        self.inner.start_run(run, seed)

    def describe(self) -> dict | None:
        describe = getattr(self.inner, "describe", None)
        return None if describe is None else {**describe(), "live_pictures": "query picture"}

    def live_scores(self, run: int, view: LiveView) -> np.ndarray:
        """1 on ``view.truth`` when the model names it for ``view.picture``; else all 0."""
        out = np.zeros(N_CATEGORIES, dtype=np.float32)
        if view.picture >= 0 and view.truth >= 0:
            if int(self.inner.predictions(run)[view.picture]) == view.truth:
                out[view.truth] = 1.0
        return out

    def learn_from_live(self, run: int, view: LiveView) -> int:
        """The model's ``learn_from_collision`` of the query picture of the side the robot hit."""
        if view.picture < 0:
            return -1
        return int(self.inner.learn_from_collision(run, view.picture, view.truth))

    def support_accuracy(self, run: int) -> float:
        """The share of the query pictures the model names right in run ``run``."""
        return float(np.mean(self.inner.predictions(run) == TRUE_CATEGORY))


class LiveSupportSet:
    """A few-shot network (paper section 3.2.1, eq. 2; or a Prototypical Network) on live
    pictures, around a loaded :class:`SupportSetRecogniser` (its runs, support sets and table):
    the picture is resized to the checkpoint's input (bilinear, as ``fewshot.data.load_image``),
    normalised with its statistics, embedded, and scored against the run's current class states.

    The dynamic support set (section 3.3) substitutes the live picture:
    :meth:`learn_from_live` gives it a member code ``LIVE_CODE_BASE +`` 48 bits of its bytes'
    SHA-256 (the same picture is the same member everywhere, so the shared score columns stay
    right) and puts it at the position the substitution way chooses."""

    LIVE_CODE_BASE = 1 << 20

    def __init__(self, recogniser: SupportSetRecogniser):
        if recogniser.checkpoint is None:
            raise ValueError(
                "live pictures need a recogniser loaded from a checkpoint (from_files)"
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

    def _parts(self, image: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        im = Image.fromarray(np.asarray(image, dtype=np.uint8))
        if im.size != (self.size, self.size):
            im = im.resize((self.size, self.size), Image.Resampling.BILINEAR)
        return self.inner.outside_parts(to_tensor(np.array(im)[None], self._mean, self._std))

    def live_scores(self, run: int, view: LiveView) -> np.ndarray:
        """Scores (C,) of the live picture; ``view.truth`` and ``view.picture`` are not read."""
        return self.inner.score_outside(run, self._parts(view.image)[1])

    def learn_from_live(self, run: int, view: LiveView) -> int:
        """Substitute the live picture into ``view.truth``'s support members (the world tells the
        category of what the robot hit, as in the grid world); the position, or -1."""
        data = np.ascontiguousarray(view.image, dtype=np.uint8).tobytes()
        code = self.LIVE_CODE_BASE + int.from_bytes(hashlib.sha256(data).digest()[:6], "big")
        return self.inner.substitute_outside(run, code, self._parts(view.image)[0], view.truth)

    def support_accuracy(self, run: int) -> float:
        """The share of the query pictures run ``run``'s support set recognises."""
        return float(np.mean(self.inner.predictions(run) == self.inner.query_categories))
