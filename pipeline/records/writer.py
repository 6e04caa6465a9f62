"""The MCAP record writer, :class:`RecordWriter`: the episode sink (``pipeline/rl/sink.py``) that
records every episode of every run, one ``EpisodeBatch`` message a sink batch, on a thread of its
own (docs/records.md "The writer"). Same input, same bytes.
"""

from __future__ import annotations

import functools
import operator
import os
import queue
import threading
import time
import zlib
from collections.abc import Mapping, Sequence
from importlib import metadata as _im
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.records import Chunk, Message
from mcap.writer import Writer

from . import schema as S
from .batch_check import check_batch
from .codec import encode_batch
from .config_text import ConfigText, config_text, to_json

OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
VERSION_PACKAGES = (
    *("fewshot-safe-rl-pipeline", "numpy", "numba", "pandas", "torch", "mujoco", "mcap"),
    *("mcap-protobuf-support", "protobuf", "foxglove-schemas-protobuf", "rerun-sdk"),
    *("hydra-core", "omegaconf", "gymnasium"),
)
SUBSTITUTION_KEYS = tuple(f.name for f in S.MESSAGES["Substitutions"])  # of substitution()
PICTURES = S.TOPIC_PICTURES + "/<picture id>"
TIME = "log_time_ns = run * 1e15 + episode * 1e9 + step * 1e6 (1 ms a step, 1 s an episode)"
_FLUSH, _STOP = object(), object()  # queue items besides batches
QUEUE = 256  # batches: a chunk of the runner's (one a run) fits; at most 32,768 steps each


@functools.cache
def package_versions() -> dict[str, str]:
    """Versions of the packages that shape the results, from the installed metadata."""
    import platform

    def version(name: str) -> str:
        try:
            return _im.version(name)
        except _im.PackageNotFoundError:
            return "not installed"

    return {"python": platform.python_version()} | {n: version(n) for n in VERSION_PACKAGES}


def _metadata(meta: dict, maze, runs, level: str) -> list[tuple[str, dict[str, str]]]:
    """The MCAP metadata records (docs/records.md "The schema")."""
    head = {"format_version": S.FORMAT_VERSION, "library": S.LIBRARY, "record": level, "time": TIME}
    out = [("recording", head | {"episodes_topic": S.TOPIC_EPISODES, "pictures_topic": PICTURES})]
    if (config := meta.pop("config", None)) is not None:
        text = config if isinstance(config, ConfigText) else config_text(config)
        out.append(("config", text._asdict()))
    if "seeds" in meta:
        out.append(("seeds", {"json": to_json(meta.pop("seeds"))}))
    versions = {str(k): str(v) for k, v in dict(meta.pop("versions", None) or {}).items()}
    out.append(("versions", package_versions() | versions))
    if maze is not None:
        rows, rest = list(maze["layout"]), dict(maze)
        mz = {"layout": "\n".join(rows), "height": str(len(rows)), "width": str(len(rows[0]))}
        mz["cell_index"], _ = "row * width + col", rest.pop("layout")
        mz |= {k: to_json(rest.pop(k)) for k in ("categories", "moves") if rest.get(k) is not None}
        if rest.get("actions") is not None:  # comma-separated names
            mz["actions"] = ",".join(map(str, rest.pop("actions")))
        rest.pop("actions", None), rest.pop("categories", None), rest.pop("moves", None)
        out.append(("maze", mz | ({"extra": to_json(rest)} if rest else {})))
    if runs is not None:
        out.append(("obstacles", {"json": _obstacles_json(runs), "keys": ",".join(OBSTACLE_KEYS)}))
    if meta:
        out.append(("info", {str(k): to_json(v) for k, v in sorted(meta.items())}))
    return out


def _obstacles_json(runs: Sequence | Mapping) -> str:
    """Each run's obstacles as :func:`.config_text.to_json` writes ``{run: [{key: int}]}`` (keys
    sorted), put together as text: a cell of a study writes one, and ``json.dumps`` of a thousand
    small dicts took most of the time a record file takes to open (tested: the same text)."""
    items = runs.items() if isinstance(runs, Mapping) else enumerate(runs)
    by_run = sorted((str(int(r)), obstacles) for r, obstacles in items)
    keys = sorted(OBSTACLE_KEYS)
    one = "{" + ",".join(f'"{k}":%d' for k in keys) + "}"  # printf-style: the fastest here
    values = operator.itemgetter(*keys)
    listed = (
        f'"{run}":[' + ",".join([one % values(o) for o in obstacles]) + "]"
        for run, obstacles in by_run
    )
    return "{" + ",".join(listed) + "}"


def _image(frame_id: str, data: bytes) -> bytes:
    """A ``foxglove.CompressedImage`` message of PNG or JPEG bytes."""
    fmt = (
        "png"
        if data[:8] == b"\x89PNG\r\n\x1a\n"
        else "jpeg"
        if data[:3] == b"\xff\xd8\xff"
        else None
    )
    if fmt is None:
        raise ValueError(f"{frame_id}: pictures must be PNG or JPEG bytes")
    return S.CompressedImage(frame_id=frame_id, data=bytes(data), format=fmt).SerializeToString()


class RecordWriter:
    """Writes one MCAP file of episode records; the episode sink of ``pipeline/rl/sink.py``.

    ``path`` ends in ``.mcap``; ``metadata``: ``config`` (dict, OmegaConf or YAML/JSON string),
    ``seeds``, ``versions`` (over the installed package versions), other JSON-able keys (``info``);
    ``maze``: ``layout`` (rows of ``S``/``G``/``X``/``.``), ``categories``, ``actions``, ``moves``,
    other keys; ``runs``: per run (list or dict) the obstacles ``{cell, physical, category,
    instance, orientation}``; ``pictures``: query picture id -> PNG/JPEG bytes;
    ``support_pictures``: category -> K initial thumbnails; ``steps``: record every step
    (``record=steps``) or, False, only what happens per episode (``record=episodes``).

    Batches are checked, encoded and written on the writer's own thread, behind a queue of
    :data:`QUEUE` batches (the caller waits only when it is full). A chunk is closed every ``flush_every``
    episodes (where chunks end is part of the bytes, so never by the clock); once ``flush_seconds``
    pass with episodes not yet in a closed chunk, they are written after the last one as a
    provisional chunk that the next chunk overwrites: a killed run keeps them, and a finished file
    has the same bytes. An error on the thread is raised by the next call, naming the file.
    ``fsync=False``: ``close`` leaves flushing the finished file to the disk to the caller (the
    trials stage writes into a staging folder that :func:`pipeline.files.swap_in` syncs at once).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        metadata: Mapping[str, Any] | None = None,
        maze: Mapping[str, Any] | None = None,
        runs: Sequence | Mapping | None = None,
        pictures: Mapping[int, bytes] | None = None,
        support_pictures: Mapping[int, Sequence[bytes]] | None = None,
        flush_every: int = 100,
        flush_seconds: float = 2.0,
        steps: bool = True,
        fsync: bool = True,
    ):
        self.path = Path(path)
        if self.path.suffix != ".mcap":
            raise ValueError(f"record file name must end in .mcap, got {self.path}")
        self.partial_path = self.path.with_name(self.path.name + ".partial")
        self.records_steps, self.flush_every, self.flush_seconds = steps, flush_every, flush_seconds
        self.fsync = fsync
        self.n_episodes = self.n_substitutions = self._since_flush = 0
        self._next_episode: dict[int, int] = {}  # run -> first episode not yet recorded
        self._subs: dict[int, list[tuple]] = {}  # run -> substitutions waiting for their batch
        self._pending: list[tuple[int, bytes]] = []  # messages since the last closed chunk
        self._provisioned = 0  # of them, in the provisional chunk on disk
        self._flushed_at, self._error, self._closed = time.monotonic(), None, False
        self.thread_cpu_seconds = 0.0  # CPU time of the writer's thread, once it has ended
        records = _metadata(dict(metadata or {}), maze, runs, "steps" if steps else "episodes")
        images = [
            (f"{S.TOPIC_PICTURES}/{p}", _image(f"picture_{p}", pictures[p]))
            for p in sorted(pictures or {})
        ]
        for c, shots in sorted((support_pictures or {}).items()):
            images += [
                (f"{S.TOPIC_SUPPORT}/{c}/{k}", _image(f"support_{c}_{k}", d))
                for k, d in enumerate(shots)
            ]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.partial_path, "wb")
        # data CRCs: a flipped byte outside the chunks is found too (docs/reliability.md)
        self._mcap = Writer(self._file, chunk_size=8 * 2**20, enable_data_crcs=True)
        self._mcap.start(profile="", library=S.LIBRARY)
        # schemas 1-2, then channel 1 /episodes: the reader falls back on this layout
        ids = [
            self._mcap.register_schema(
                cls.DESCRIPTOR.full_name, "protobuf", S.file_descriptor_set(cls)
            )
            for cls in (S.EpisodeBatch, S.CompressedImage)
        ]
        self._channel = self._mcap.register_channel(S.TOPIC_EPISODES, "protobuf", ids[0])
        for name, data in records:
            self._mcap.add_metadata(name, data)
        for topic, data in images:
            channel = self._mcap.register_channel(topic, "protobuf", ids[1])
            self._mcap.add_message(channel, log_time=0, publish_time=0, data=data)
        self._mcap.flush()  # the pictures and channel definitions in a complete first chunk
        self._queue: queue.Queue = queue.Queue(maxsize=QUEUE)
        self._thread = threading.Thread(
            target=self._serve, name=f"records {self.path}", daemon=True
        )
        self._thread.start()

    def episodes(self, **batch: Any) -> None:
        """Record a batch of consecutive finished episodes of one run (``pipeline/rl/sink.py``)
        as ONE ``EpisodeBatch`` message, with the substitutions recorded for its episodes."""
        self._check()
        run, eps = int(batch["run"]), np.asarray(batch["episode"])
        if eps.ndim == 1 and len(eps):  # else checked (and refused) on the thread
            first, last = int(eps[0]), int(eps[-1])
            S.log_time_ns(run, first), S.log_time_ns(run, last)  # range checks
            if first < self._next_episode.get(run, 0):
                raise ValueError(
                    f"episode batch of run {run}, episodes {first}..{last}: episodes of a run must "
                    f"be recorded once and in order; {self.path} already has run {run} up to "
                    f"episode {self._next_episode[run] - 1}"
                )
            waiting = self._subs.get(run, [])
            if k := next((i for i, s in enumerate(waiting) if s[0] > last), len(waiting)):
                batch["substitutions"] = dict(
                    zip(SUBSTITUTION_KEYS, map(np.array, zip(*waiting[:k])))
                )
                del waiting[:k]
            self._next_episode[run] = last + 1
        self._queue.put(batch)

    def substitution(
        self, *, run, episode, step, picture, category, position, support_accuracy=float("nan")
    ) -> None:
        """Record that ``picture`` replaced shot ``position`` of class ``category`` (section 3.3)
        and the support set's accuracy on the query pictures after it; ``picture = -1``
        (position -1): the support set a run starts with. Written with its episode's batch."""
        self._check()
        run = int(run)
        S.log_time_ns(run, int(episode), int(step))  # range check
        self._subs.setdefault(run, []).append(
            (episode, step, picture, category, position, support_accuracy)
        )

    def flush(self) -> None:
        """Close the current chunk: everything recorded so far survives a kill."""
        self._check()
        self._queue.put(_FLUSH)
        self._queue.join()
        self._check()

    def close(self, *, complete: bool = True) -> Path:
        """Finish the file (summary and index) and rename it to its final name; with
        ``complete=False`` (an interrupted run), or after an error on the writer's thread, it
        keeps its ``.partial`` name. Returns the path of the file."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)
            self._thread.join()
            self.complete = complete and self._error is None
            try:
                closed = {"complete": str(self.complete).lower(), "episodes": str(self.n_episodes)}
                self._mcap.add_metadata(
                    "closed", closed | {"substitutions": str(self.n_substitutions)}
                )
                self._mcap.finish()
                self._file.truncate()  # a provisional chunk past the end
                self._file.flush()
                if self.fsync:
                    os.fsync(self._file.fileno())
            finally:
                self._file.close()
            if self.complete:
                os.replace(self.partial_path, self.path)
        if self._error is not None:
            self._raise()
        return self.path if self.complete else self.partial_path

    def _check(self) -> None:
        if self._closed:
            raise RuntimeError(f"record writer for {self.path} is closed")
        if self._error is not None:
            self._raise()

    def _raise(self):
        e, where = self._error, self.partial_path
        if isinstance(e, OSError):
            raise OSError(e.errno, e.strerror or str(e), str(where)) from e
        if isinstance(e, (ValueError, TypeError)):
            raise type(e)(f"{where}: {e}") from e
        raise RuntimeError(f"{where}: the record writer failed: {type(e).__name__}: {e}") from e

    def _serve(self) -> None:
        """The writer's thread: the batches in the order they came (so the same bytes)."""
        start = time.thread_time()
        try:
            self._serve_queue()
        finally:
            self.thread_cpu_seconds = time.thread_time() - start

    def _serve_queue(self) -> None:
        while True:
            new = len(self._pending) > self._provisioned  # messages no chunk on disk holds
            wait = self._flushed_at + self.flush_seconds - time.monotonic() if new else None
            try:
                item = self._queue.get(timeout=None if wait is None else max(wait, 0))
            except queue.Empty:
                self._guard(self._provisional)
                continue
            try:
                step = (
                    self._mcap.flush if item is _STOP else self._chunk if item is _FLUSH else None
                )
                self._guard(step or functools.partial(self._write, item))
            finally:
                self._queue.task_done()
            if item is _STOP:
                return

    def _guard(self, step) -> None:
        if self._error is None:
            try:
                step()
            except BaseException as e:  # raised to the caller by its next call
                self._error = e

    def _write(self, batch: dict) -> None:
        b = check_batch(batch, with_steps=self.records_steps)
        if len(b["episode"]):
            t = S.log_time_ns(b["run"], int(b["episode"][0]))
            data = encode_batch(b)
            self._mcap.add_message(self._channel, log_time=t, publish_time=t, data=data)
            self._pending.append((t, data))
            self.n_episodes += len(b["episode"])
            self.n_substitutions += len(b["cols"]["Substitutions"].get("episode", ()))
            self._since_flush += len(b["episode"])
            if self._since_flush >= self.flush_every:
                self._chunk()

    def _chunk(self) -> None:
        """Close the current chunk (over a provisional one, whose leftover bytes go)."""
        self._mcap.flush()
        self._file.truncate()
        self._pending, self._since_flush, self._flushed_at = [], 0, time.monotonic()
        self._provisioned = 0

    def _provisional(self) -> None:
        """The messages since the last closed chunk as an uncompressed chunk at the end of the
        file, written through to disk; the writer goes on from where that chunk starts. Built from
        ``mcap.records`` (a chunk's data is its message records, back to back)."""
        messages = RecordBuilder()
        for t, data in self._pending:
            Message(self._channel, log_time=t, data=data, publish_time=t, sequence=0).write(
                messages
            )
        raw, times = messages.end(), [t for t, _ in self._pending]
        chunk = Chunk(
            compression="",
            data=raw,
            message_start_time=min(times),
            message_end_time=max(times),
            uncompressed_crc=zlib.crc32(raw),
            uncompressed_size=len(raw),
        )
        out = RecordBuilder()
        chunk.write(out)
        at = self._file.tell()
        self._file.write(out.end())
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.seek(at)
        self._flushed_at, self._provisioned = time.monotonic(), len(self._pending)

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            self.close(complete=exc_type is None)
        except Exception:
            if exc_type is None:  # the writer's own error; else the caller's goes on
                raise
