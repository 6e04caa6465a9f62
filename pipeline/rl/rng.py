"""One seeding scheme for everything (STYLE.md: "one way to do each thing").

``run_seeds(seed, run)`` derives a run's independent streams from numpy's ``SeedSequence`` with
spawn key ``(run,)``: a run's results do not depend on how many runs are in the batch. The agent's
stream is a splitmix64 generator whose 64-bit state lives in an array, so the numba kernels and the
Gymnasium agent draw the very same numbers and a paused run resumes exactly where it stopped.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numba as nb
import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0


@dataclass(frozen=True)
class RunSeeds:
    placement: int  # numpy Generator seed for the obstacle placement
    agent: int  # initial splitmix64 state of the agent's stream
    recogniser: int  # seed handed to Recogniser.start_run (support-set substitutions)


@functools.lru_cache(maxsize=1 << 16)  # asked for by every cell of a study, run by run
def run_seeds(seed: int, run: int) -> RunSeeds:
    if seed < 0 or run < 0:
        raise ValueError(f"seed and run must be non-negative (seed={seed}, run={run})")
    words = np.random.SeedSequence(seed, spawn_key=(run,)).generate_state(3, dtype=np.uint64)
    return RunSeeds(int(words[0]), int(words[1]), int(words[2]))


@nb.njit(cache=True, inline="always")
def next_u64(state: np.ndarray, i: int) -> np.uint64:
    """splitmix64 step of ``state[i]`` (Steele, Lea and Flood 2014)."""
    x = state[i] + _GOLDEN
    state[i] = x
    z = x
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@nb.njit(cache=True, inline="always")
def uniform(state: np.ndarray, i: int) -> float:
    """A float in [0, 1) with 53 random bits."""
    return float(next_u64(state, i) >> _S11) * _INV53


@nb.njit(cache=True, inline="always")
def randint(state: np.ndarray, i: int, n: int) -> int:
    """An integer in [0, n)."""
    return int(uniform(state, i) * n)
