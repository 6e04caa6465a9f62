"""A batch's step columns (``states``, ``actions``, ``flags``, ``rewards``: one entry a step) checked
and turned into their payloads in one compiled pass (docs/records.md "The writer").

The step columns are nearly all of a recording's bytes. Checked and encoded by numpy, each column
went through six to ten whole-array operations (ranges, casts, the reward test, the zigzag), about
10 ns of CPU a step; two compiled loops read each value once. It gives what the codec
(:mod:`.codec`) writes: a code column whose values are all below 128 as their own bytes (the
varint of such a value is the value), and the rewards as signed bytes when they are all whole
numbers in -64..63 (``Steps.small_rewards``). What does not fit goes on as before: a code column
with larger values through the Protobuf runtime, rewards as float32.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

CODE_COLUMNS = ("states", "actions", "flags")  # in the order of :class:`StepColumns`' bounds
SMALL_REWARDS = (-64, 63)  # a sint32 zigzag varint of one byte


class StepColumns(NamedTuple):
    """What :func:`scan_steps` found: per code column its lowest and highest value and, when all
    are in 0..127, its bytes; the rewards as int8 when all are whole in -64..63, else None."""

    low: tuple[int, int, int]
    high: tuple[int, int, int]
    one_byte: tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]
    small_rewards: np.ndarray | None


@nb.njit(cache=True, nogil=True)
def _code_bytes(values, out):
    """Fill ``out`` with the low byte of each of ``values``; return their lowest and highest."""
    low = high = np.int64(values[0]) if values.shape[0] else np.int64(0)
    for i in range(values.shape[0]):  # one loop the compiler vectorises
        v = np.int64(values[i])
        low, high = min(low, v), max(high, v)
        out[i] = np.uint8(v & 0xFF)
    return low, high


@nb.njit(cache=True, nogil=True)
def _small_rewards(rewards, out):
    """Fill ``out`` with the rewards as int8 and return whether each is a whole number in
    -64..63 (NaN is not). No early exit and no branch: one loop the compiler vectorises (with an
    early exit it cost 3.6 times as much a step); ``out`` means nothing when the answer is False."""
    fits = True
    for i in range(rewards.shape[0]):
        r = rewards[i]
        in_range = -64.0 <= r <= 63.0  # False for NaN
        whole = np.int64(r if in_range else 0.0)  # converting only what fits: never undefined
        fits &= in_range & (np.float64(whole) == r)
        out[i] = np.int8(whole)
    return fits


def scan_steps(
    states: np.ndarray, actions: np.ndarray, flags: np.ndarray, rewards: np.ndarray
) -> StepColumns:
    """One pass over four 1-D columns of equal length: integer ``states``, ``actions``, ``flags``
    (booleans count as 0/1) and float ``rewards``."""
    columns = [a.view(np.uint8) if a.dtype.kind == "b" else a for a in (states, actions, flags)]
    codes, small = np.empty((len(columns), len(states)), np.uint8), np.empty(len(rewards), np.int8)
    bounds = [_code_bytes(a, out) for a, out in zip(columns, codes)]
    low, high = (tuple(int(b[k]) for b in bounds) for k in (0, 1))
    one_byte = tuple(codes[j] if low[j] >= 0 and high[j] < 128 else None for j in range(3))
    return StepColumns(low, high, one_byte, small if _small_rewards(rewards, small) else None)
