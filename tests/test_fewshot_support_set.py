"""The four substitution ways of the dynamic support set (paper section 3.3, Figure 5), pinned for
one seed, and their defining properties for many seeds."""

from itertools import combinations

import numpy as np
import pytest

from pipeline.fewshot.support_set import (
    SUPPORT_READS,
    PositionChooser,
    SupportSet,
    original_member,
    ways_agree_until,
)


def _sequence(way, seed=7, n=15):
    rng = np.random.default_rng(seed)
    chooser = PositionChooser(way, 5)
    return [chooser.next_position(rng) for _ in range(n)]


def test_pinned_sequences_for_seed_7():
    assert _sequence(1) == [0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 0, 1, 2, 3, 4]
    assert _sequence(2) == [4, 3, 3, 4, 2, 3, 4, 1, 0, 1, 1, 4, 4, 0, 2]
    assert _sequence(3) == [4, 2, 3, 1, 0, 2, 4, 3, 0, 1, 0, 2, 1, 4, 3]
    assert _sequence(4) == [4, 2, 3, 1, 0, 4, 2, 3, 1, 0, 4, 2, 3, 1, 0]


@pytest.mark.parametrize("seed", range(20))
def test_way_properties(seed):
    way3 = _sequence(3, seed, 20)
    for r in range(4):  # every round of way 3 replaces each position once
        assert sorted(way3[5 * r : 5 * r + 5]) == [0, 1, 2, 3, 4]
    way4 = _sequence(4, seed, 20)
    assert sorted(way4[:5]) == [0, 1, 2, 3, 4]
    assert way4[5:] == way4[:5] * 3  # then the first round's order, in order
    way2 = _sequence(2, seed, 200)
    assert set(way2) == {0, 1, 2, 3, 4}


def test_way_2_repeats_positions_way_3_does_not_within_a_round():
    seqs = [_sequence(2, s, 5) for s in range(50)]
    assert any(len(set(s)) < 5 for s in seqs)


def test_position_state_is_per_category():
    s = SupportSet(5, 5, 1, seed=0)
    assert s.substitute(0, 10) == 0
    assert s.substitute(0, 11) == 1
    assert s.substitute(2, 20) == 0  # category 2 starts its own order
    assert s.substitute(0, 12) == 2
    assert s.members[0, :3].tolist() == [10, 11, 12]
    assert s.members[0, 3] == original_member(3)
    assert s.members[2, 0] == 20 and s.members[2, 1] == original_member(11)


def test_static_support_set_and_bad_input():
    s = SupportSet(5, 5, 0, seed=0)
    before = s.members.copy()
    assert s.substitute(1, 9) == -1
    np.testing.assert_array_equal(s.members, before)
    with pytest.raises(ValueError, match="substitution way"):
        SupportSet(5, 5, 5, seed=0)
    with pytest.raises(ValueError, match="category 7"):
        SupportSet(5, 5, 1, seed=0).substitute(7, 0)


def _seen(members: np.ndarray, reads: str) -> list:
    """What a recogniser that ``reads`` the support set sees of it."""
    if reads == "positions":
        return members.tolist()
    return [sorted(row[row >= 0].tolist()) for row in members]


@pytest.mark.parametrize("reads", [r for r in SUPPORT_READS if r != "nothing"])
def test_ways_agree_until_the_declared_count(reads):
    """Over seeded random runs (categories and pictures of each collision), two ways give the same
    support set (as ``reads`` sees it) while no category has taken more than
    ``ways_agree_until`` substitutions, and they do differ past it where it is exact."""
    rng = np.random.default_rng(3)
    first_difference = {}  # (a, b) -> fewest substitutions of a category when they first differed
    for _ in range(400):
        seed = int(rng.integers(2**31))
        sets = {w: SupportSet(5, 5, w, seed) for w in range(5)}
        counts = np.zeros(5, int)
        for _ in range(int(rng.integers(1, 16))):
            category, picture = int(rng.integers(5)), int(rng.integers(6))
            counts[category] += 1
            for s in sets.values():
                s.substitute(category, 5 * picture + category)
            for a, b in combinations(range(5), 2):
                if _seen(sets[a].members, reads) != _seen(sets[b].members, reads):
                    first_difference.setdefault((a, b), 99)
                    first_difference[(a, b)] = min(first_difference[(a, b)], counts.max() - 1)
    for a, b in combinations(range(5), 2):
        agree = ways_agree_until(a, b, 5, reads)
        seen = first_difference.get((a, b))
        if agree is None:
            assert seen is None, (a, b)
        else:
            assert seen is not None and seen >= agree, (a, b, seen, agree)
    exact = {(3, 4): 5} | ({(1, 3): 5, (1, 2): 1} if reads == "substituted" else {(1, 3): 0})
    assert {k: first_difference[k] for k in exact} == exact
    assert ways_agree_until(2, 2, 5) is None
    assert [ways_agree_until(a, 4, 5, "nothing") for a in (0, 1, 2, 3)] == [0, None, None, None]
    with pytest.raises(ValueError, match="reads"):
        ways_agree_until(1, 2, 5, "pixels")
