"""The dynamic support set and its four substitution ways (paper section 3.3, Figure 5).

After a collision the robot learns the obstacle's true category and the picture it took
substitutes one of the K samples of that category. Which position is replaced:

- way 1, *in order*: positions 0, 1, ..., K-1, 0, 1, ... (one in, one out);
- way 2, *random*: a uniformly random position every time, even the one just replaced;
- way 3, *random rounds*: a random position among those not yet replaced in the current round;
  after all K were replaced a new round starts;
- way 4, *random then in order*: like way 3 for the first round, then the first round's order
  repeated, as way 1 does with 0..K-1.

Way 0 means a static support set (no substitution). The position state is kept per category;
one random stream per run (seeded in :meth:`SupportSet.reset_stream`) serves every category.

Members are integers: an original support picture ``j`` (its index in the support split, class
``c`` holding ``c*K .. c*K+K-1``) is ``-(j + 1)``; a query picture is its picture id (>= 0).
"""

from __future__ import annotations

import numpy as np

WAYS = (0, 1, 2, 3, 4)
WAY_NAMES = {
    0: "static",
    1: "in order",
    2: "random",
    3: "random rounds",
    4: "random round, then in order",
}


def original_member(j: int) -> int:
    """Member code of original support picture ``j``."""
    return -(j + 1)


class PositionChooser:
    """Which support position of one category the next substitution replaces (ways 1-4)."""

    def __init__(self, way: int, k_shot: int) -> None:
        if way not in (1, 2, 3, 4):
            raise ValueError(f"substitution way must be 1, 2, 3 or 4, got {way}")
        self.way, self.k = way, k_shot
        self.count = 0  # substitutions made so far in this category
        # way 3/4: positions not yet replaced this round
        self.round_left: list[int] = list(range(k_shot))
        self.first_round: list[int] = []  # way 4: the first round's order

    def next_position(self, rng: np.random.Generator) -> int:
        k = self.k
        if self.way == 1:
            pos = self.count % k
        elif self.way == 2:
            pos = int(rng.integers(k))
        elif self.way == 3 or (self.way == 4 and self.count < k):
            pos = self.round_left.pop(int(rng.integers(len(self.round_left))))
            if self.way == 4:
                self.first_round.append(pos)
            if not self.round_left:
                self.round_left = list(range(k))
        else:  # way 4 after its first round
            pos = self.first_round[self.count % k]
        self.count += 1
        return pos


class SupportSet:
    """The C-way K-shot support set of one run: ``members`` (C, K) and one
    :class:`PositionChooser` per category."""

    def __init__(self, n_way: int, k_shot: int, way: int, seed: int) -> None:
        if way not in WAYS:
            raise ValueError(f"substitution way must be one of {WAYS} (0 = static), got {way}")
        self.n_way, self.k_shot, self.way = n_way, k_shot, way
        self.members = np.array(
            [[original_member(c * k_shot + k) for k in range(k_shot)] for c in range(n_way)],
            dtype=np.int64,
        )
        self.choosers = [PositionChooser(way, k_shot) for _ in range(n_way)] if way else []
        self.reset_stream(seed)

    def reset_stream(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def substitute(self, category: int, member: int) -> int:
        """Put ``member`` into ``category`` at the position the way chooses; return that position
        (or -1 for a static set, which is left unchanged)."""
        if not 0 <= category < self.n_way:
            raise ValueError(f"category {category} out of range 0..{self.n_way - 1}")
        if self.way == 0:
            return -1
        pos = self.choosers[category].next_position(self.rng)
        self.members[category, pos] = member
        return pos


def started(runs: dict, run: int):
    """Run ``run``'s entry of a recogniser's ``runs``; a run not started is a ``KeyError`` that
    names the call to make."""
    try:
        return runs[run]
    except KeyError:
        raise KeyError(f"run {run} was not started; call start_run({run}, seed) first") from None


def check_picture(categories: np.ndarray, picture_id: int, category: int) -> None:
    """Refuse a picture id outside ``categories`` (each query picture's true category) or a
    picture that does not show ``category``."""
    if not 0 <= picture_id < len(categories):
        raise ValueError(f"picture id {picture_id} out of range 0..{len(categories) - 1}")
    if categories[picture_id] != category:
        raise ValueError(
            f"picture {picture_id} shows category {categories[picture_id]}, not {category}"
        )


#: What of the support set a recogniser's predictions read (its class's ``reads_support``): the
#: shot at every position (``positions``, assumed of a recogniser that declares nothing), only
#: which substituted pictures each category holds, however placed (``substituted``), or nothing a
#: way changes (``nothing``: a recogniser without support positions, whatever the way).
SUPPORT_READS = ("positions", "substituted", "nothing")


def ways_agree_until(a: int, b: int, k_shot: int, reads: str = "positions") -> int | None:
    """How many substitutions every category of a run can take with ways ``a`` and ``b`` still
    giving the same support set, as a recogniser that ``reads`` it sees it (section 3.3, Figure 5):
    in a run where no category takes more, the two ways cannot change anything; None: never can.

    Ways 3 and 4 draw the same positions from the same stream until a category's first round of
    K substitutions is over (way 4 then repeats that round's order, way 3 draws a new one): they
    agree up to K substitutions a category. Read by position, any other pair may differ from the
    first substitution on. Read by members, positions do not matter: ways 1 and 4 replace the
    oldest substituted picture once all K originals are out, so they always hold the same
    pictures; ways 1 and 3 differ in which picture leaves only from a category's K+1-th
    substitution; way 2 may replace a substituted picture from a category's second substitution
    on; way 0 (static) differs from any other way at the first. A recogniser that reads
    ``nothing`` of the positions cannot tell ways 1-4 apart."""
    if reads not in SUPPORT_READS:
        raise ValueError(f"reads must be one of {SUPPORT_READS}, got {reads!r}")
    for way in (a, b):
        if way not in WAYS:
            raise ValueError(f"substitution way must be one of {WAYS}, got {way}")
    pair = frozenset((a, b))
    if a == b:
        return None
    if 0 in pair:
        return 0
    if reads == "nothing":
        return None
    if pair == {3, 4}:
        return k_shot
    if reads == "positions":
        return 0
    if 2 in pair:
        return 1
    return None if pair == {1, 4} else k_shot
