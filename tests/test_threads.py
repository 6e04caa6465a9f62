"""One thread budget (pipeline/threads.py): the split of the cores, and that applying it sets numba
and torch (torch only once imported)."""

import numba
import pytest
import torch

from pipeline import threads
from pipeline.threads import ThreadBudget, torch_budget, trials_budget


@pytest.fixture
def restore_threads():
    before = numba.get_num_threads(), torch.get_num_threads()
    yield
    numba.set_num_threads(before[0])
    torch.set_num_threads(before[1])


@pytest.mark.parametrize(
    ("given", "workers", "cores", "numba_threads"),
    [(0, 1, 2, 2), (0, 2, 2, 1), (0, 3, 2, 1), (1, 1, 2, 1), (2, 2, 2, 2), (0, 2, 8, 4)],
)
def test_trials_budget_shares_the_cores(monkeypatch, given, workers, cores, numba_threads):
    monkeypatch.setattr(threads, "cores", lambda: cores)
    assert trials_budget(given, workers) == ThreadBudget(workers, numba_threads, 1)


def test_apply_sets_both_libraries(restore_threads):
    ThreadBudget(1, 1, 1).apply()
    assert (numba.get_num_threads(), torch.get_num_threads()) == (1, 1)
    torch_budget(2).apply()
    assert (numba.get_num_threads(), torch.get_num_threads()) == (1, 2)


def test_a_budget_asks_numba_for_no_more_than_it_has(restore_threads):
    ThreadBudget(1, 10_000, None).apply()
    assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS
