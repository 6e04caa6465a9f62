"""The one pass over a batch's step columns (pipeline/records/step_columns.py): what it finds and
the payloads it gives, against plain numpy."""

import numpy as np
import pytest

from pipeline.records.step_columns import pairs, scan_steps


def columns(n=1000, seed=0):
    rng = np.random.default_rng(seed)
    states = rng.integers(0, 121, n).astype(np.int32)
    actions = rng.integers(0, 4, n).astype(np.int8)
    flags = rng.integers(0, 32, n).astype(np.uint8)
    rewards = rng.choice(np.array([-1, 0, 1], np.float32), n)
    return states, actions, flags, rewards


def test_one_byte_pairs_and_small_rewards_match_numpy():
    states, actions, flags, rewards = columns()
    found = scan_steps(states, actions, flags, rewards)
    for j, a in enumerate((states, actions, flags)):
        assert (found.low[j], found.high[j]) == (int(a.min()), int(a.max()))
    assert found.transitions.dtype == np.uint8
    assert found.transitions[0::2].tolist() == states.tolist()
    assert found.transitions[1::2].tolist() == (actions.astype(int) * 32 + flags).tolist()
    assert found.small_rewards.dtype == np.int8
    assert np.array_equal(found.small_rewards, rewards)


@pytest.mark.parametrize(
    "reward", [0.5, np.nan, np.inf, -65.0, 64.0, 1e12], ids=lambda r: f"reward {r}"
)
def test_a_reward_that_is_not_a_small_whole_number_keeps_the_floats(reward):
    states, actions, flags, rewards = columns()
    rewards[-1] = reward
    assert scan_steps(states, actions, flags, rewards).small_rewards is None


@pytest.mark.parametrize(
    ("column", "value"), [(0, 128), (1, 4)], ids=["a cell of 128", "a fifth action"]
)
def test_the_edges_of_one_byte_pairs_and_small_rewards(column, value):
    """Cells up to 127 and four actions (action * 32 + flags below 128) are one byte a value;
    past either edge the pairs go on as int64 for the runtime's varints, the same values."""
    parts = list(columns(4))
    parts[3][:] = [-64, 63, 0, -1]
    parts[0][:] = [0, 127, 5, 6]
    parts[1][:] = [0, 3, 1, 2]
    parts[2][:] = [0, 31, 1, 2]
    found = scan_steps(*parts)
    assert found.transitions.dtype == np.uint8 and found.small_rewards is not None
    parts[column][1] = value
    found = scan_steps(*parts)
    assert found.transitions.dtype == np.int64 and found.high[column] == value
    assert found.transitions.tolist() == pairs(*parts[:3]).tolist()
    assert found.transitions[3] == int(parts[1][1]) * 32 + 31


def test_negative_and_huge_values_are_found_and_booleans_count_as_bytes():
    states = np.array([3, -7, 2**40], np.int64)
    flags = np.array([True, False, True])
    found = scan_steps(states, np.zeros(3, np.int8), flags, np.zeros(3, np.float32))
    assert (found.low[0], found.high[0]) == (-7, 2**40)
    assert (found.low[2], found.high[2]) == (0, 1)
    assert found.transitions.dtype == np.int64  # the caller refuses the values


def test_empty_columns():
    empty = np.zeros(0, np.int32)
    found = scan_steps(empty, empty, empty, np.zeros(0, np.float32))
    assert len(found.transitions) == 0 and len(found.small_rewards) == 0
