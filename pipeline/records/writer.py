"""The MCAP record writer, :class:`RecordWriter`: an episode sink (``pipeline/rl/sink.py``) that
records every episode of every run, one ``EpisodeBatch`` message a sink batch, on a thread of its
own (docs/records.md "The writer"). Same input, same bytes.
"""

from __future__ import annotations

import functools
import json
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
from mcap._chunk_builder import ChunkBuilder
from mcap.data_stream import RecordBuilder
from mcap.records import Chunk, Message
from mcap.writer import CompressionType, Writer

from . import schema as S
from .batch_check import check_batch
from .codec import encode_batch

OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
VERSION_PACKAGES = (
    *("fewshot-safe-rl-pipeline", "numpy", "numba", "pandas", "torch", "mujoco", "mcap"),
    *("mcap-protobuf-support", "protobuf", "foxglove-schemas-protobuf", "rerun-sdk"),
    *("hydra-core", "omegaconf", "gymnasium"),
)
SUBSTITUTION_KEYS = tuple(f.name for f in S.MESSAGES["Substitutions"])  # of substitution()
COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}
_FLUSH, _STOP = object(), object()  # queue items besides batches


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


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer, np.floating, np.bool_, np.ndarray)):
        return o.tolist()
    if isinstance(o, (set, frozenset, tuple, Path)):
        return str(o) if isinstance(o, Path) else list(o)
    raise TypeError(f"cannot record a {type(o).__name__} in the metadata (value {o!r})")


def to_json(obj: Any) -> str:
    if type(obj).__module__.startswith("omegaconf"):
        from omegaconf import OmegaConf

        obj = OmegaConf.to_container(obj, resolve=True)
    return json.dumps(obj, default=_json_default, sort_keys=True, separators=(",", ":"))


def _image(frame_id: str, data: bytes) -> bytes:
    """A ``foxglove.CompressedImage`` message of PNG, JPEG or WebP bytes."""
    data = bytes(data)
    for fmt, ok in (
        ("png", data[:8] == b"\x89PNG\r\n\x1a\n"),
        ("jpeg", data[:3] == b"\xff\xd8\xff"),
        ("webp", data[:4] == b"RIFF" and data[8:12] == b"WEBP"),
    ):
        if ok:
            return S.CompressedImage(frame_id=frame_id, data=data, format=fmt).SerializeToString()
    raise ValueError(
        "pictures must be PNG, JPEG or WebP bytes (Foxglove's CompressedImage formats)"
    )


def _maze_record(maze: Mapping[str, Any]) -> dict[str, str]:
    rows = list(maze["layout"])
    out = {"layout": "\n".join(rows), "height": str(len(rows)), "width": str(len(rows[0]))}
    out["cell_index"] = "row * width + col"
    if maze.get("categories") is not None:
        out["categories"] = to_json(list(maze["categories"]))
    if maze.get("actions") is not None:  # comma-separated names
        out["actions"] = ",".join(str(n) for n in maze["actions"])
    if maze.get("moves") is not None:
        out["moves"] = to_json(np.asarray(maze["moves"]))
    extra = {k: v for k, v in maze.items() if k not in ("layout", "categories", "actions", "moves")}
    return out | ({"extra": to_json(extra)} if extra else {})


def _metadata_records(metadata: dict, maze, runs, level: str) -> list[tuple[str, dict[str, str]]]:
    import yaml

    recording = {"format_version": S.FORMAT_VERSION, "library": S.LIBRARY, "record": level}
    recording["time"] = (
        "log_time_ns = run * 1e15 + episode * 1e9 + step * 1e6 (1 ms a step, 1 s an episode)"
    )
    recording |= {
        "episodes_topic": S.TOPIC_EPISODES,
        "pictures_topic": S.TOPIC_PICTURES + "/<picture id>",
    }
    out = [("recording", recording)]
    if (config := metadata.pop("config", None)) is not None:
        parsed = yaml.safe_load(config) if isinstance(config, str) else json.loads(to_json(config))
        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml: the same text, faster
        text = (
            config if isinstance(config, str) else yaml.dump(parsed, Dumper=dumper, sort_keys=True)
        )
        out.append(("config", {"yaml": text, "json": to_json(parsed)}))
    if "seeds" in metadata:
        out.append(("seeds", {"json": to_json(metadata.pop("seeds"))}))
    versions = {str(k): str(v) for k, v in dict(metadata.pop("versions", None) or {}).items()}
    out.append(("versions", package_versions() | versions))
    if maze is not None:
        out.append(("maze", _maze_record(maze)))
    if runs is not None:
        items = runs.items() if isinstance(runs, Mapping) else enumerate(runs)
        placed = {
            str(int(r)): [{k: int(o[k]) for k in OBSTACLE_KEYS} for o in obs] for r, obs in items
        }
        out.append(("obstacles", {"json": to_json(placed), "keys": ",".join(OBSTACLE_KEYS)}))
    if metadata:
        out.append(("info", {str(k): to_json(v) for k, v in sorted(metadata.items())}))
    return out


class RecordWriter:
    """Writes one MCAP file of episode records; the episode sink of ``pipeline/rl/sink.py``
    (:meth:`episodes`, :meth:`substitution`).

    ``path`` ends in ``.mcap``; ``metadata``: ``config`` (dict, OmegaConf or YAML/JSON string),
    ``seeds``, ``versions`` (over the installed package versions), other JSON-able keys (``info``);
    ``maze``: ``layout`` (rows of ``S``/``G``/``X``/``.``), ``categories``, ``actions``, ``moves``,
    other keys; ``runs``: per run (list or dict) the obstacles ``{cell, physical, category,
    instance, orientation}``; ``pictures``: query picture id -> PNG/JPEG/WebP bytes;
    ``support_pictures``: category -> K initial thumbnails; ``steps``: record every step
    (``record=steps``) or, False, only what happens per episode (``record=episodes``).

    Batches are checked, encoded and written on the writer's thread, behind a queue of
    ``queue_size`` batches (the caller waits only when it is full). A chunk is closed every
    ``flush_every`` episodes (where chunks end is part of the bytes, so never by the clock); when
    ``flush_seconds`` pass with episodes not yet in a closed chunk, they are written after the last
    closed chunk as a provisional chunk that the next chunk overwrites: a killed run keeps them,
    a finished file has the same bytes. An error on the thread is raised by the next call, naming
    the file.
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
        compression: str = "zstd",
        chunk_size: int = 8 * 2**20,
        steps: bool = True,
        queue_size: int = 8,
    ):
        self.path = Path(path)
        if self.path.suffix != ".mcap":
            raise ValueError(f"record file name must end in .mcap, got {self.path}")
        self.partial_path = self.path.with_name(self.path.name + ".partial")
        self.records_steps, self.flush_every, self.flush_seconds = (
            bool(steps),
            flush_every,
            flush_seconds,
        )
        self.n_episodes = self.n_substitutions = 0
        self._next_episode: dict[int, int] = {}  # run -> first episode not yet recorded
        self._subs: dict[int, list[tuple]] = {}  # run -> substitutions waiting for their batch
        self._pending: list[tuple[int, bytes]] = []  # messages since the last closed chunk
        self._since_flush, self._flushed_at, self._error, self._closed = (
            0,
            time.monotonic(),
            None,
            False,
        )
        level = "steps" if steps else "episodes"
        records = _metadata_records(dict(metadata or {}), maze, runs, level)
        images = [
            (f"{S.TOPIC_PICTURES}/{int(p)}", f"picture_{int(p)}", pictures[p])
            for p in sorted(pictures or {})
        ]
        support = support_pictures or {}
        images += [
            (f"{S.TOPIC_SUPPORT}/{int(c)}/{k}", f"support_{int(c)}_{k}", data)
            for c in sorted(support)
            for k, data in enumerate(support[c])
        ]
        images = [(topic, _image(frame, data)) for topic, frame, data in images]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.partial_path, "wb")
        # enable_data_crcs: a flipped byte outside the chunks is detected too (docs/reliability.md)
        self._mcap = Writer(
            self._file,
            chunk_size=chunk_size,
            compression=COMPRESSION[compression],
            enable_data_crcs=True,
        )
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
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self._thread = threading.Thread(
            target=self._serve, name=f"records {self.path}", daemon=True
        )
        self._thread.start()

    def episodes(self, **batch: Any) -> None:
        """Record a batch of consecutive finished episodes of one run (columnar fields as in
        ``pipeline/rl/sink.py``) as ONE ``EpisodeBatch`` message, with the substitutions recorded
        for its episodes."""
        self._check()
        run, eps = int(batch["run"]), np.asarray(batch["episode"])
        if eps.ndim != 1 or not len(eps):
            return self._queue.put(batch)  # checked (and refused) on the thread
        first, last = int(eps[0]), int(eps[-1])
        S.log_time_ns(run, first), S.log_time_ns(run, last)  # range checks
        if first < self._next_episode.get(run, 0):
            raise ValueError(
                f"episode batch of run {run}, episodes {first}..{last}: episodes of a run must be "
                f"recorded once and in order; {self.path} already has run {run} up to episode "
                f"{self._next_episode[run] - 1}"
            )
        waiting = self._subs.get(run, [])
        k = next((i for i, s in enumerate(waiting) if s[0] > last), len(waiting))
        if k:
            batch = dict(
                batch, substitutions=dict(zip(SUBSTITUTION_KEYS, map(np.array, zip(*waiting[:k]))))
            )
            del waiting[:k]
        self._next_episode[run] = last + 1
        self._queue.put(batch)

    def substitution(
        self,
        *,
        run: int,
        episode: int,
        step: int,
        picture: int,
        category: int,
        position: int,
        support_accuracy: float = float("nan"),
    ) -> None:
        """Record that ``picture`` replaced shot ``position`` of class ``category`` (section 3.3)
        and the support set's accuracy on the query pictures after it; ``picture = -1``
        (position -1): the support set a run starts with. Written with its episode's batch."""
        self._check()
        S.log_time_ns(int(run), int(episode), int(step))  # range check
        sub = (episode, step, picture, category, position, support_accuracy)
        self._subs.setdefault(int(run), []).append(sub)

    def flush(self) -> None:
        """Write everything recorded so far in a closed chunk: it survives a kill."""
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
            complete = complete and self._error is None
            try:
                closed = {"complete": str(complete).lower(), "episodes": str(self.n_episodes)}
                self._mcap.add_metadata(
                    "closed", closed | {"substitutions": str(self.n_substitutions)}
                )
                self._mcap.finish()
                self._file.truncate()  # a provisional chunk past the end
                self._file.flush()
                os.fsync(self._file.fileno())
            finally:
                self._file.close()
            if complete:
                os.replace(self.partial_path, self.path)
        if self._error is not None:
            self._raise()
        return self.path if complete else self.partial_path

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
        """The writer's thread: batches in the order they came, then the closing flush."""
        while True:
            wait = (
                self._flushed_at + self.flush_seconds - time.monotonic() if self._pending else None
            )
            try:
                item = self._queue.get(timeout=None if wait is None else max(wait, 0))
            except queue.Empty:
                self._guard(self._provisional)
                continue
            try:
                if item is _STOP:
                    return self._guard(self._mcap.flush)
                self._guard(self._chunk if item is _FLUSH else lambda: self._write(item))
            finally:
                self._queue.task_done()

    def _guard(self, step) -> None:
        if self._error is None:
            try:
                step()
            except BaseException as e:  # raised to the caller by its next call
                self._error = e

    def _write(self, batch: dict) -> None:
        b = check_batch(batch, with_steps=self.records_steps)
        if not len(b["episode"]):
            return
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

    def _provisional(self) -> None:
        """The messages since the last closed chunk, as an uncompressed chunk at the end of the
        file, written through to disk; the writer goes on from where that chunk starts."""
        chunk, out = ChunkBuilder(), RecordBuilder()
        for t, data in self._pending:
            chunk.add_message(Message(self._channel, t, data, t, 0))
        raw = chunk.end()
        times = {
            "message_start_time": chunk.message_start_time,
            "message_end_time": chunk.message_end_time,
        }
        Chunk(
            **times,
            uncompressed_size=len(raw),
            uncompressed_crc=zlib.crc32(raw),
            compression="",
            data=raw,
        ).write(out)
        at = self._file.tell()
        self._file.write(out.end())
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.seek(at)
        self._flushed_at = time.monotonic()

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            self.close(complete=exc_type is None)
        except Exception:
            if exc_type is None:  # an error of the writer's own; else the caller's goes on
                raise
