"""The one pass over a batch's step columns (pipeline/records/step_columns.py): what it finds and
the payloads it gives, against plain numpy."""

import numpy as np
import pytest

from pipeline.records.step_columns import scan_steps


def columns(n=1000, seed=0):
    rng = np.random.default_rng(seed)
    states = rng.integers(0, 121, n).astype(np.int32)
    actions = rng.integers(0, 4, n).astype(np.int8)
    flags = rng.integers(0, 32, n).astype(np.uint8)
    rewards = rng.choice(np.array([-1, 0, 1], np.float32), n)
    return states, actions, flags, rewards


def test_one_byte_columns_and_small_rewards_match_numpy():
    states, actions, flags, rewards = columns()
    found = scan_steps(states, actions, flags, rewards)
    for j, a in enumerate((states, actions, flags)):
        assert (found.low[j], found.high[j]) == (int(a.min()), int(a.max()))
        assert found.one_byte[j].dtype == np.uint8
        assert np.array_equal(found.one_byte[j], a)
    assert found.small_rewards.dtype == np.int8
    assert np.array_equal(found.small_rewards, rewards)


@pytest.mark.parametrize(
    "reward", [0.5, np.nan, np.inf, -65.0, 64.0, 1e12], ids=lambda r: f"reward {r}"
)
def test_a_reward_that_is_not_a_small_whole_number_keeps_the_floats(reward):
    states, actions, flags, rewards = columns()
    rewards[-1] = reward
    assert scan_steps(states, actions, flags, rewards).small_rewards is None


def test_the_edges_of_one_byte_values_and_small_rewards():
    states, actions, flags, rewards = columns(4)
    rewards[:] = [-64, 63, 0, -1]
    states[:] = [0, 127, 5, 6]
    found = scan_steps(states, actions, flags, rewards)
    assert found.one_byte[0] is not None and found.small_rewards is not None
    states[1] = 128
    found = scan_steps(states, actions, flags, rewards)
    assert found.one_byte[0] is None and found.high[0] == 128  # the runtime writes its varints


def test_negative_and_huge_values_are_found_and_booleans_count_as_bytes():
    states = np.array([3, -7, 2**40], np.int64)
    flags = np.array([True, False, True])
    found = scan_steps(states, np.zeros(3, np.int8), flags, np.zeros(3, np.float32))
    assert (found.low[0], found.high[0]) == (-7, 2**40) and found.one_byte[0] is None
    assert np.array_equal(found.one_byte[2], [1, 0, 1])


def test_empty_columns():
    empty = np.zeros(0, np.int32)
    found = scan_steps(empty, empty, empty, np.zeros(0, np.float32))
    assert all(len(b) == 0 for b in found.one_byte) and len(found.small_rewards) == 0
