"""Scores computed once: a category's column of the (pictures x categories) score table, kept by
what it depends on and shared by every recogniser of a process that scores the same way.

A column (every query picture's raw score against one category's class state, paper eq. 2) is a
pure function of the network's weights, the query and support pictures as the network sees them
(after resizing, normalising and any hue shift of the colour test), the recogniser's kind, and the
multiset of the category's support members. The **source** key hashes the first three from the
very tensors the recogniser was built with, so two recognisers share columns exactly when they
would compute the same numbers, whatever path built them (files, tests, another substitution
way). Within a source a column is keyed by its members in the one order the class state sums
them (:func:`pipeline.fewshot.support_recogniser.canonical`), so a stored column is the very bits
a recomputation would give and the records are the same bytes with and without the store.

The store lives for the process: the cells of an experiment, and the cells a worker process
runs one after another, reuse what earlier cells computed (worker processes do not share: the
generalisation study needs a few hundred distinct columns in all). :func:`disabled` turns sharing
off (every column is then computed as before, within a run only), for tests and benchmarks that
compare the two.
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Callable, Iterator

import numpy as np
import torch


class ColumnStore:
    """Columns of one source by member tuple, with hit and miss counts."""

    def __init__(self, keep: bool = True) -> None:
        self._columns: dict[tuple[int, ...], np.ndarray] = {}
        self._keep = keep
        self.hits = 0
        self.misses = 0

    def column(self, members: tuple[int, ...], compute: Callable[[], np.ndarray]) -> np.ndarray:
        """The column of ``members``, computed by ``compute`` the first time (read-only)."""
        got = self._columns.get(members)
        if got is not None:
            self.hits += 1
            return got
        self.misses += 1
        got = compute()
        got.setflags(write=False)
        if self._keep:
            self._columns[members] = got
        return got

    def __len__(self) -> int:
        return len(self._columns)


_STORES: dict[str, ColumnStore] = {}
_UNSHARED: list[ColumnStore] = []  # made while disabled(), counted by statistics()
_SHARING = [True]


def source_key(kind: str, network: torch.nn.Module, *tensors: torch.Tensor) -> str:
    """The sha256 of what every column of a recogniser depends on besides its members: its kind,
    the network's parameters and buffers (names, shapes, values) and the pictures it scores."""
    h = hashlib.sha256(kind.encode())
    for name, value in network.state_dict().items():
        h.update(name.encode())
        h.update(repr(tuple(value.shape)).encode())
        h.update(value.detach().contiguous().cpu().numpy().tobytes())
    for t in tensors:
        h.update(repr((tuple(t.shape), str(t.dtype))).encode())
        h.update(t.detach().contiguous().cpu().numpy().tobytes())
    return h.hexdigest()


def store_for(source: str) -> ColumnStore:
    """The process's store for ``source`` (a fresh, unshared one while :func:`disabled`)."""
    if not _SHARING[0]:
        _UNSHARED.append(ColumnStore(keep=False))
        return _UNSHARED[-1]
    return _STORES.setdefault(source, ColumnStore())


def statistics() -> dict[str, int]:
    """Columns kept, hits and misses (columns computed) over every store of this process since
    the last :func:`clear`."""
    stores = [*_STORES.values(), *_UNSHARED]
    return {
        "columns": sum(len(s) for s in stores),
        "hits": sum(s.hits for s in stores),
        "misses": sum(s.misses for s in stores),
    }


def clear() -> None:
    """Forget every shared column and the counts (recognisers already built keep their stores)."""
    _STORES.clear()
    _UNSHARED.clear()


@contextlib.contextmanager
def disabled() -> Iterator[None]:
    """Recognisers built inside this block share nothing: each computes every column it needs
    (once per run and invalidation, as without the store)."""
    _SHARING[0] = False
    try:
        yield
    finally:
        _SHARING[0] = True
