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
runs one after another, reuse what earlier cells computed. :func:`disabled` turns sharing off
(every column is then computed as before, within a run only), for tests and benchmarks that
compare the two.

**Between runs** the columns are kept on disk, one file a source (:func:`cache_folder`: the
folder ``$FSRL_SCORE_CACHE`` names, by default ``$XDG_CACHE_HOME/fewshot-safe-rl/score-columns``
or ``~/.cache/...``; ``FSRL_SCORE_CACHE=off`` (or ``0``, ``false``, ``no``, ``none``) keeps them
in memory only). A store reads its file when it is made, and every process writes what it
computed at its exit (:func:`save_all`), merged with what the file holds then, atomically and
under a lock, so the worker processes of a study, which end together, keep each other's columns. The file's name hashes the source with torch's version and the kernel path the
process took (:mod:`pipeline.kernels`), the two things besides the source that decide a column's
bits: a column read back is the column this process would compute, so the records are the same
bytes cold or warm (tested). A file that cannot be read (damaged, another layout) is set aside
with a warning: its columns are computed again and the file is written anew.

A store may also keep what a recogniser loaded from files needs to start without its network
(:attr:`ColumnStore.about`: the checkpoint's model, the pictures' categories): such a recogniser
imports torch and loads its checkpoint only at its first column not in the file
(:mod:`.from_files`). This module imports no torch.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import importlib.metadata
import json
import os
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.files import atomic_output
from pipeline.torch_later import kernel_path

#: The environment variable naming the folder of the score files, and the values that mean none.
CACHE_VARIABLE = "FSRL_SCORE_CACHE"
CACHE_OFF = frozenset({"off", "0", "false", "no", "none"})


class ScoreCacheWarning(UserWarning):
    """A score file could not be read: its columns are computed again."""


class ColumnStore:
    """Columns of one source by member tuple, with hit and miss counts; ``path``: its score file
    (read now, written by :meth:`save`), or None."""

    def __init__(self, keep: bool = True, path: Path | None = None) -> None:
        self._columns: dict[tuple[int, ...], np.ndarray] = {}
        self._keep = keep
        self.hits = 0
        self.misses = 0
        self.path = path if keep else None
        self.loaded = 0  # columns read from the file
        self._unsaved = 0  # columns computed (or an about given) since the file was read or written
        self._about: dict[str, Any] | None = None
        if self.path is not None:
            columns, self._about = read_score_file(self.path)
            self._columns.update(columns)
            self.loaded = len(self._columns)

    @property
    def about(self) -> dict[str, Any] | None:
        """What the source's recogniser needs to start without computing (JSON-able), if known."""
        return self._about

    @about.setter
    def about(self, about: dict[str, Any]) -> None:
        if self._keep and about != self._about:
            self._about = about
            self._unsaved += 1

    def save(self) -> None:
        """Write the columns computed since the last read or write to :attr:`path`, with those
        already there (another process's too)."""
        if self.path is None or not self._unsaved:
            return
        with _locked(self.path):  # the workers of a study end together: none loses another's
            theirs, their_about = read_score_file(self.path, warn=False)  # damaged: warned at read
            write_columns(self.path, theirs | self._columns, self._about or their_about)
        self._unsaved = 0

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
            self._unsaved += 1
        return got

    def __len__(self) -> int:
        return len(self._columns)


_STORES: dict[str, ColumnStore] = {}
_UNSHARED: list[ColumnStore] = []  # made while disabled(), counted by statistics()
_SHARING = [True]
_SAVED_AT_EXIT = [False]  # whether save_all is registered to run at the process's exit


def source_key(kind: str, network, *tensors) -> str:
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
    if source not in _STORES:
        folder = cache_folder()
        path = None if folder is None else folder / f"{file_key(source)}.npz"
        _STORES[source] = ColumnStore(path=path)
        if path is not None and not _SAVED_AT_EXIT[0]:
            atexit.register(save_all)
            _SAVED_AT_EXIT[0] = True
    return _STORES[source]


def cache_folder() -> Path | None:
    """The folder of the score files (module docstring), or None when ``FSRL_SCORE_CACHE=off``."""
    named = os.environ.get(CACHE_VARIABLE, "").strip()
    if named.lower() in CACHE_OFF:
        return None
    if named:
        return Path(named).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "fewshot-safe-rl" / "score-columns"


def file_key(source: str) -> str:
    """The name of ``source``'s score file: the source, torch's version and the kernel path (both
    known without importing torch: :mod:`pipeline.torch_later`)."""
    whole = f"{source}|torch {importlib.metadata.version('torch')}|kernels {kernel_path()}"
    return hashlib.sha256(whole.encode()).hexdigest()[:32]


def read_columns(path: Path, *, warn: bool = True) -> dict[tuple[int, ...], np.ndarray]:
    """The columns of a score file by member tuple (:func:`read_score_file`)."""
    return read_score_file(path, warn=warn)[0]


def read_score_file(
    path: Path, *, warn: bool = True
) -> tuple[dict[tuple[int, ...], np.ndarray], dict[str, Any] | None]:
    """The columns of a score file by member tuple and its ``about`` (({}, None) when there is no
    file, or when it cannot be read: then with a :class:`ScoreCacheWarning` unless ``warn`` is
    False)."""
    if not path.exists():
        return {}, None
    try:
        # np.load leaves a file it opened open when the zip is damaged: this one is closed
        with open(path, "rb") as file, np.load(file, allow_pickle=False) as saved:  # CRC-checked
            out = {}
            about = json.loads(str(saved[ABOUT])) if ABOUT in saved.files else None
            if about is not None and not isinstance(about, dict):
                raise ValueError(f"{ABOUT} is not a JSON object")
            for name in (n for n in saved.files if n.startswith("members_")):
                members, columns = saved[name], saved["columns_" + name.removeprefix("members_")]
                if members.ndim != 2 or columns.ndim != 2 or len(members) != len(columns):
                    raise ValueError(f"{name} and its columns do not fit together")
                if columns.dtype != np.float32 or members.dtype.kind != "i":
                    raise ValueError(f"{name}: unexpected types {members.dtype}, {columns.dtype}")
                columns.setflags(write=False)
                out.update(zip(map(tuple, members.tolist()), columns))
            return out, about
    except Exception as exc:  # damaged or not a score file: computed again, written anew
        if not warn:
            return {}, None
        warnings.warn(
            f"{path}: not a readable score file ({type(exc).__name__}: {exc}); its columns are "
            "computed again and the file is written anew",
            ScoreCacheWarning,
            stacklevel=2,
        )
        return {}, None


#: The score file's array holding :attr:`ColumnStore.about` as JSON text.
ABOUT = "about_json"


def write_columns(
    path: Path, columns: dict[tuple[int, ...], np.ndarray], about: dict[str, Any] | None = None
) -> None:
    """Write ``columns`` (member tuple -> column) as a score file, atomically: an array of member
    tuples and one of columns for each tuple length, in sorted order (the same columns, the same
    bytes), and ``about`` as JSON text, when given."""
    arrays = {} if about is None else {ABOUT: np.array(json.dumps(about, sort_keys=True))}
    for k in sorted({len(m) for m in columns}):
        keys = sorted(m for m in columns if len(m) == k)
        arrays[f"members_{k}"] = np.array(keys, dtype=np.int64).reshape(len(keys), k)
        arrays[f"columns_{k}"] = np.stack([columns[m] for m in keys]).astype(np.float32)
    with atomic_output(path, fsync=False) as f:  # a cache: remade if a crash loses it
        np.savez(f, **arrays)


def save_all() -> None:
    """Write every shared store's new columns to its score file. A folder that cannot be written
    is not an error of the run: its columns are computed again next time (with a warning)."""
    for store in list(_STORES.values()):
        try:
            store.save()
        except OSError as exc:
            message = f"{store.path}: the score columns were not kept ({exc})"
            warnings.warn(message, ScoreCacheWarning, stacklevel=2)


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold ``path``'s lock file (``<name>.lock`` beside it) while merging into it, so processes
    saving at once each keep the other's columns (POSIX ``flock``; elsewhere, no lock)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: two processes saving at once may miss each other's columns
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_name(path.name + ".lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file is closed
        yield


def statistics() -> dict[str, int]:
    """Columns kept, hits, misses (columns computed) and columns read from score files over every
    store of this process since the last :func:`clear`."""
    stores = [*_STORES.values(), *_UNSHARED]
    return {
        "columns": sum(len(s) for s in stores),
        "hits": sum(s.hits for s in stores),
        "misses": sum(s.misses for s in stores),
        "loaded": sum(s.loaded for s in stores),
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
