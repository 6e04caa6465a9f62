"""The four substitution ways of the dynamic support set (paper section 3.3, Figure 5), pinned for
one seed, and their defining properties for many seeds."""

import numpy as np
import pytest

from pipeline.fewshot.support_set import PositionChooser, SupportSet, original_member


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
