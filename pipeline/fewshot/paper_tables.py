"""The paper's recogniser as its Tables 1 and 2 report it (section 4.2.1): a recogniser whose chance
of naming a query picture right is the paper's measured accuracy, so the trials can separate what
the method does from how well our Relation Network sees (docs/fewshot.md "The paper's recognition").

For category ``t`` (0 chair, 1 kettle, 2 carton, 3 basin, 4 basket), with ``n`` of its five support
positions holding substituted query pictures (the dynamic support set, section 3.3):

* a picture of ``t`` that is **not** in the support set is named right with probability ``o_t(n)``:
  ``o_t(0)`` the original support set's score (Table 1's first row: 0/8, 3/8, 2/8, 8/8, 4/8);
  ``o_t(1)`` Table 1's "no same picture" diagonal (95/700, 596/700, 331/700, 697/700, 487/700);
  ``o_t(n)``, n = 2..5, the rise ``o_t(1) - o_t(0)`` scaled by Table 2's no-same-picture means,
  ``(B_n - B_0) / (B_1 - B_0)`` with B = 42.5, 48.04, 48.46, 48.41, 48.68, 48.60%: Table 2 gives
  only the mean over categories, so every category is taken to rise in n as that mean does;
* a picture of ``t`` that **is** in the support set (substituted, not yet replaced) is named right
  with probability ``q_t`` = (Table 1's diagonal with the same picture - without) / 100 pictures:
  (186-95, 689-596, 383-331, 792-697, 577-487) / 100 = 0.91, 0.93, 0.52, 0.95, 0.90;
* ``n`` is at most 5 (all five positions), so nothing lies beyond the tables; a substitution that
  replaces an earlier substituted picture puts that picture back under ``o_t``;
* substitutions in other categories leave ``t`` as it is: Table 1's off-diagonal cells (a
  substitution in one category moves the others, kettle by up to +48 points) are left out, since
  the tables say nothing of how they combine; so one substitution gives a mean of 47.1% (with the
  same picture) where the paper measured 49.03%, five 49.4% against 54.91%;
* a wrong picture is named as one of the four other categories, uniformly (the tables give no
  confusions); wrong costs a collision whichever it names.

Draws: at ``start_run`` each picture gets two uniforms from the run's seed, ``u`` for "not in the
support set" and ``v`` for "in it"; a picture is right while its uniform lies below its current
probability. Within a category ``u`` is stratified, ``u = (rank + w) / 8`` with a random rank
permutation and one uniform ``w``, so the original support set names exactly 0, 3, 2, 8 and 4
pictures right in every run, and any probability ``p`` gives ``8p`` right pictures on average
(floor or ceiling of it). The same seed gives the same predictions; ``v`` is independent of ``u``,
so a picture substituted after a collision is right with probability ``q_t`` whatever made it fail.
Substitution positions follow the run's way (:class:`~.support_set.SupportSet`, the same stream
and positions as the Relation Network's for the same seed).
"""

from __future__ import annotations

import numpy as np

from .accuracy_study import PAPER_BASELINE, PAPER_TABLE1, PAPER_TABLE2
from .support_set import SupportSet, check_picture, started

#: Table 1, first row: pictures of each category named right with the original support set (of 8).
ORIGINAL = np.array(PAPER_BASELINE["correct"]) / 8
#: Table 1, the substituted category's own cell, one substitution: with the substituted picture
#: counted (of 800) and without it ("no same picture", of 700).
WITH_SAME = np.diagonal(PAPER_TABLE1["with_same"])
NO_SAME = np.diagonal(PAPER_TABLE1["no_same"])
#: Table 2, mean accuracy (%) without the substituted pictures, n = 0..5 substitutions.
TABLE2_NO_SAME = np.array([no_same for _, no_same in PAPER_TABLE2.values()]) * 100

N_WAY, K_SHOT, PER_CATEGORY = 5, 5, 8  # the paper's 5-way 5-shot set, 8 query pictures a category
N_PICTURES = N_WAY * PER_CATEGORY
#: True category of every query picture id (``pipeline.world.pictures``: 8 consecutive ids each).
CATEGORY = np.repeat(np.arange(N_WAY), PER_CATEGORY)


def not_in_support(n: np.ndarray | int) -> np.ndarray:
    """``o_t(n)`` for every category t: (5,) for a scalar n, (..., 5) for an array of counts."""
    n = np.clip(np.asarray(n), 0, K_SHOT)
    scale = (TABLE2_NO_SAME - TABLE2_NO_SAME[0]) / (TABLE2_NO_SAME[1] - TABLE2_NO_SAME[0])
    rise = NO_SAME / (PER_CATEGORY - 1) / 100 - ORIGINAL
    return np.clip(ORIGINAL + rise * scale[n][..., None], 0.0, 1.0)


#: ``q_t``: a picture of t that is one of t's support shots.
IN_SUPPORT = (WITH_SAME - NO_SAME) / 100


class PaperTablesRecogniser:
    """``conf/recogniser/paper_tables.yaml``: the paper's recognition accuracy (module
    docstring); ``substitution_way`` 0 is the static support set, 1-4 section 3.3's ways."""

    kind = "paper_tables"
    """Its name in the records (``describe()``)."""
    display_name = "paper's Tables 1-2"
    """The report's name for it (``pipeline.report.names``); never recorded."""
    colour = "#8c564b"
    """Its colour in the report's figures; never recorded."""
    reads_support = "substituted"
    """What of the support set its predictions read (:data:`~.support_set.SUPPORT_READS`): which
    substituted pictures each category holds and how many, never their positions or the original
    shots (:meth:`probabilities`); the report's claims derive from it where the four ways cannot
    differ (:func:`~.support_set.ways_agree_until`)."""

    def __init__(self, substitution_way: int = 0, carry_over: bool = False):
        SupportSet(N_WAY, K_SHOT, substitution_way, 0)  # validates the way
        self.substitution_way, self.carry_over = substitution_way, carry_over
        self._runs: dict[int, tuple[SupportSet, np.ndarray, np.ndarray, np.ndarray]] = {}
        #: run -> (its support members' bytes, its predictions under them): the runner asks after
        #: every substitution and again for the scores of the recognitions made meanwhile
        self._predicted: dict[int, tuple[bytes, np.ndarray]] = {}

    def start_run(self, run: int, seed: int) -> None:
        """Restore the original support set and draw the run's uniforms (with ``carry_over`` an
        existing run keeps both and only reseeds its substitution stream)."""
        if self.carry_over and run in self._runs:
            self._runs[run][0].reset_stream(seed)
            return
        rng = np.random.default_rng([seed, 0x7AB1E5])
        ranks = np.concatenate([rng.permutation(PER_CATEGORY) for _ in range(N_WAY)])
        u = (ranks + np.repeat(rng.random(N_WAY), PER_CATEGORY)) / PER_CATEGORY
        v = rng.random(N_PICTURES)
        wrong = (CATEGORY + rng.integers(1, N_WAY, size=N_PICTURES)) % N_WAY
        self._runs[run] = (SupportSet(N_WAY, K_SHOT, self.substitution_way, seed), u, v, wrong)
        self._predicted.pop(run, None)  # new draws: the same members may be named otherwise

    def probabilities(self, run: int) -> np.ndarray:
        """Each query picture's chance of being named right under run ``run``'s support set."""
        members = self._run(run)[0].members
        n = (members >= 0).sum(axis=1)  # substituted positions of each category
        p = np.diagonal(not_in_support(n))[CATEGORY]  # category t at its own n_t
        inside = np.isin(np.arange(N_PICTURES), members[members >= 0])
        return np.where(inside, IN_SUPPORT[CATEGORY], p)

    def predictions(self, run: int) -> np.ndarray:
        support, u, v, wrong = self._run(run)
        members = support.members
        known = self._predicted.get(run)
        if known is None or known[0] != members.tobytes():
            inside = np.isin(np.arange(N_PICTURES), members[members >= 0])
            right = np.where(inside, v, u) < self.probabilities(run)
            known = members.tobytes(), np.where(right, CATEGORY, wrong).astype(np.int64)
            self._predicted[run] = known
        return known[1].copy()

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        """One-hot on the predicted category (this model has no relation scores)."""
        ids = np.asarray(picture_ids, dtype=np.int64)
        if ids.size and (ids.min() < 0 or ids.max() >= N_PICTURES):
            raise ValueError(f"picture ids must lie in 0..{N_PICTURES - 1}, got {ids.tolist()}")
        return np.eye(N_WAY, dtype=np.float32)[self.predictions(run)[ids]]

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        """Substitute the picture into its category at the position the way chooses (section
        3.3); return the position, or -1 for the static support set."""
        check_picture(CATEGORY, picture_id, true_category)
        return self._run(run)[0].substitute(true_category, int(picture_id))

    def replace(self, run: int, category: int, position: int, picture_id: int) -> None:
        """Put ``picture_id`` at ``position`` of ``category`` (the accuracy study's substitutions)."""
        check_picture(CATEGORY, picture_id, category)
        if not 0 <= position < K_SHOT:
            raise ValueError(f"support position {position} out of range 0..{K_SHOT - 1}")
        self._run(run)[0].members[category, position] = int(picture_id)

    def support_members(self, run: int) -> np.ndarray:
        """(C, K) member codes (``support_set.py``): query picture ids or original shots."""
        return self._run(run)[0].members.copy()

    def describe(self) -> dict:
        """What the records keep: its kind, way and the tables it follows."""
        return {
            "kind": self.kind,
            "source": "Wang et al. 2024, Tables 1 and 2",
            "substitution_way": self.substitution_way,
            "carry_over": self.carry_over,
        }

    def _run(self, run: int):
        return started(self._runs, run)
