"""The MCAP record writer, :class:`RecordWriter`: an episode sink (``pipeline/rl/sink.py``) that records every
episode of every run, one ``EpisodeBatch`` message a sink batch (docs/records.md "The writer": the atomic finish,
checksums, flushing, what is checked; schema in :mod:`.schema`, encoding in :mod:`.codec`). Same input, same bytes.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Mapping, Sequence
from importlib import metadata as _im
from pathlib import Path
from typing import Any

import numpy as np
from mcap.writer import CompressionType, Writer

from . import schema as S
from .batch_check import check_batch
from .codec import encode_batch

LAYOUT_CHARS = frozenset("SGX.")
OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
VERSION_PACKAGES = (
    "fewshot-safe-rl-pipeline",
    "numpy",
    "numba",
    "pandas",
    "torch",
    "mujoco",
    "mcap",
    "mcap-protobuf-support",
    "protobuf",
    "foxglove-schemas-protobuf",
    "rerun-sdk",
    "hydra-core",
    "omegaconf",
    "gymnasium",
)
SUBSTITUTION_KEYS = tuple(f.name for f in S.MESSAGES["Substitutions"])  # of the substitution() call
COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


@functools.cache
def package_versions() -> dict[str, str]:
    """Versions of the packages that shape the results, read from the installed metadata once a
    process, without importing the packages."""
    import platform

    def version(name: str) -> str:
        try:
            return _im.version(name)
        except _im.PackageNotFoundError:
            return "not installed"

    return {"python": platform.python_version()} | {
        name: version(name) for name in VERSION_PACKAGES
    }


def _plain(obj: Any) -> Any:
    """Configs (dicts, OmegaConf containers, numpy values) as plain JSON-able Python."""
    if type(obj).__module__.startswith("omegaconf"):
        from omegaconf import OmegaConf

        return OmegaConf.to_container(obj, resolve=True)
    return obj


def _json_default(o: Any) -> Any:
    for types, to in (
        ((np.integer, np.floating, np.bool_, np.ndarray), lambda o: o.tolist()),
        ((set, frozenset, tuple), list),
        (Path, str),
    ):
        if isinstance(o, types):
            return to(o)
    raise TypeError(f"cannot record a {type(o).__name__} in the metadata (value {o!r})")


def to_json(obj: Any) -> str:
    return json.dumps(_plain(obj), default=_json_default, sort_keys=True, separators=(",", ":"))


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


def _check_maze(maze: Mapping[str, Any]) -> dict[str, str]:
    if "layout" not in maze:
        raise ValueError("maze: missing key 'layout' (list of row strings of 'S', 'G', 'X', '.')")
    rows = list(maze["layout"])
    if not rows or any(len(r) != len(rows[0]) for r in rows):
        raise ValueError(f"maze.layout: rows must be non-empty and of equal length, got {rows!r}")
    bad = set("".join(rows)) - LAYOUT_CHARS
    if bad:
        raise ValueError(
            f"maze.layout: unknown cell characters {sorted(bad)}; allowed: 'S', 'G', 'X', '.'"
        )
    out = {
        "layout": "\n".join(rows),
        "height": str(len(rows)),
        "width": str(len(rows[0])),
        "cell_index": "row * width + col",
    }
    if maze.get("categories") is not None:
        out["categories"] = to_json(list(maze["categories"]))
    names, moves = (
        maze.get("actions"),
        maze.get("moves"),
    )  # the caller's: records has no moves of its own
    if names is not None:  # comma-separated, as files have always had them
        if not (names := [str(n) for n in names]) or not all(names) or "," in "".join(names):
            raise ValueError(
                f"maze.actions: names must be non-empty and without commas, got {names!r}"
            )
        out["actions"] = ",".join(names)
    if moves is not None:
        m = np.asarray(moves)
        if m.ndim != 2 or m.shape[1] != 2 or m.dtype.kind not in "iu" or len(names or m) != len(m):
            raise ValueError(
                f"maze.moves: one (d_row, d_col) pair of integers per action name, got {moves!r}"
            )
        out["moves"] = to_json(m)
    extra = {k: v for k, v in maze.items() if k not in ("layout", "categories", "actions", "moves")}
    if extra:
        out["extra"] = to_json(extra)
    return out


def _check_runs(runs: Sequence | Mapping) -> dict[str, list[dict[str, int]]]:
    out: dict[str, list[dict[str, int]]] = {}
    for run, obstacles in runs.items() if isinstance(runs, Mapping) else enumerate(runs):
        for i, ob in enumerate(obstacles):
            if [k for k in OBSTACLE_KEYS if k not in ob]:
                raise ValueError(
                    f"runs[{run}][{i}]: obstacle assignment lacks {[k for k in OBSTACLE_KEYS if k not in ob]}; "
                    f"expected keys {list(OBSTACLE_KEYS)}"
                )
        out[str(int(run))] = [{k: int(ob[k]) for k in OBSTACLE_KEYS} for ob in obstacles]
    return out


def _metadata_records(
    metadata: dict[str, Any], maze, runs, level: str
) -> list[tuple[str, dict[str, str]]]:
    import yaml

    out = [
        (
            "recording",
            {
                "format_version": S.FORMAT_VERSION,
                "library": S.LIBRARY,
                "record": level,
                "time": "log_time_ns = run * 1e15 + episode * 1e9 + step * 1e6 (1 ms a step, 1 s an episode)",
                "episodes_topic": S.TOPIC_EPISODES,
                "pictures_topic": S.TOPIC_PICTURES + "/<picture id>",
            },
        )
    ]
    config = _plain(metadata.pop("config", None))
    if config is not None:
        parsed = yaml.safe_load(config) if isinstance(config, str) else json.loads(to_json(config))
        # libyaml's emitter where PyYAML has it (the same text as yaml.safe_dump, in less time)
        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
        text = (
            config if isinstance(config, str) else yaml.dump(parsed, Dumper=dumper, sort_keys=True)
        )
        out.append(("config", {"yaml": text, "json": to_json(parsed)}))
    if "seeds" in metadata:
        out.append(("seeds", {"json": to_json(metadata.pop("seeds"))}))
    out.append(
        (
            "versions",
            dict(package_versions())
            | {str(k): str(v) for k, v in dict(metadata.pop("versions", {}) or {}).items()},
        )
    )
    if maze is not None:
        out.append(("maze", _check_maze(maze)))
    if runs is not None:
        out.append(
            ("obstacles", {"json": to_json(_check_runs(runs)), "keys": ",".join(OBSTACLE_KEYS)})
        )
    if metadata:
        out.append(("info", {str(k): to_json(v) for k, v in sorted(metadata.items())}))
    return out


class RecordWriter:
    """Writes one MCAP file of episode records; the episode sink of ``pipeline/rl/sink.py``
    (:meth:`episodes`, :meth:`substitution`).

    ``path`` ends in ``.mcap``; ``metadata``: ``config`` (dict, OmegaConf or YAML/JSON string),
    ``seeds``, ``versions`` (over the installed package versions), other JSON-able keys (``info``);
    ``maze``: ``layout`` (rows of ``S``/``G``/``X``/``.``), ``categories``, other keys; ``runs``: per
    run (list or dict) the obstacles ``{cell, physical, category, instance, orientation}``;
    ``pictures``: query picture id -> PNG/JPEG/WebP bytes; ``support_pictures``: category -> K
    initial thumbnails; ``flush_every``: episodes a chunk; ``compression``: zstd, lz4 or none;
    ``steps``: record every step (``record=steps``) or, False, only what happens per episode
    (``record=episodes``: summaries, recognitions, unsafe-set additions, substitutions; the runner then
    keeps no step trace, see ``records_steps`` in ``pipeline/rl/sink.py``).
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
        compression: str = "zstd",
        chunk_size: int = 8 * 2**20,
        steps: bool = True,
    ):
        self.path = Path(path)
        if self.path.suffix != ".mcap":
            raise ValueError(f"record file name must end in .mcap, got {self.path}")
        if flush_every < 1:
            raise ValueError(f"flush_every must be >= 1, got {flush_every}")
        if compression not in COMPRESSION:
            raise ValueError(
                f"compression must be one of {sorted(COMPRESSION)}, got {compression!r}"
            )
        self.partial_path = self.path.with_name(self.path.name + ".partial")
        self.records_steps = bool(steps)
        self.flush_every, self.n_episodes, self.n_substitutions = int(flush_every), 0, 0
        self._since_flush, self._closed = 0, False
        self._next_episode: dict[int, int] = {}  # run -> first episode not yet recorded
        self._subs: dict[
            int, list[tuple]
        ] = {}  # run -> substitutions waiting for their episode's batch
        records = _metadata_records(
            dict(metadata or {}), maze, runs, "steps" if steps else "episodes"
        )  # validated
        images = [
            (f"{S.TOPIC_PICTURES}/{int(p)}", _image(f"picture_{int(p)}", pictures[p]))
            for p in sorted(pictures or {})
        ]
        images += [
            (f"{S.TOPIC_SUPPORT}/{int(c)}/{k}", _image(f"support_{int(c)}_{k}", data))
            for c in sorted(support_pictures or {})
            for k, data in enumerate(support_pictures[c])
        ]
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
        # schemas 1-2, then channel 1 /episodes: a reader falls back on this layout
        ids = [
            self._mcap.register_schema(
                name=cls.DESCRIPTOR.full_name, encoding="protobuf", data=S.file_descriptor_set(cls)
            )
            for cls in (S.EpisodeBatch, S.CompressedImage)
        ]
        self._ch_episodes = self._mcap.register_channel(S.TOPIC_EPISODES, "protobuf", ids[0])
        for name, data in records:
            self._mcap.add_metadata(name, data)
        for topic, data in images:
            self._mcap.add_message(
                self._mcap.register_channel(topic, "protobuf", ids[1]),
                log_time=0,
                publish_time=0,
                data=data,
            )
        self._mcap.flush()  # the pictures and channel definitions in a complete first chunk

    def episodes(self, **batch: Any) -> None:
        """Record a batch of consecutive finished episodes of one run (columnar fields as
        documented in ``pipeline/rl/sink.py``) as ONE ``EpisodeBatch`` message, with the substitutions
        recorded for its episodes."""
        self._check_open()
        run, waiting = int(batch["run"]), None
        if len(batch["episode"]) and (waiting := self._subs.get(run)):
            last = int(batch["episode"][-1])
            k = next((i for i, s in enumerate(waiting) if s[0] > last), len(waiting))
            batch = dict(
                batch, substitutions=dict(zip(SUBSTITUTION_KEYS, map(np.array, zip(*waiting[:k]))))
            )
        b = check_batch(batch, with_steps=self.records_steps)
        if not len(b["episode"]):
            return
        run, first, last = b["run"], int(b["episode"][0]), int(b["episode"][-1])
        if first < self._next_episode.get(run, 0):
            raise ValueError(
                f"episode batch of run {run}, episodes {first}..{last}: episodes of a run must "
                f"be recorded once and in order; {self.path} already has run {run} up to "
                f"episode {self._next_episode[run] - 1}"
            )
        t = S.log_time_ns(run, first, 0)
        S.log_time_ns(run, last, 0)  # range check of the last episode too
        self._mcap.add_message(self._ch_episodes, log_time=t, publish_time=t, data=encode_batch(b))
        if waiting:
            self.n_substitutions += len(b["cols"]["Substitutions"].get("episode", ()))
            del waiting[: len(b["cols"]["Substitutions"].get("episode", ()))]
        self._next_episode[run] = last + 1
        self.n_episodes, self._since_flush = (
            self.n_episodes + len(b["episode"]),
            self._since_flush + len(b["episode"]),
        )
        if self._since_flush >= self.flush_every:
            self.flush()

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
        """Record that ``picture`` replaced shot ``position`` of class ``category`` (section 3.3),
        and the accuracy of the support set on the query pictures after it. ``picture = -1``
        (position -1) records the support set a run starts with. It is written with the batch of its
        episode (substitutions of episodes never recorded are not written)."""
        self._check_open()
        S.log_time_ns(int(run), int(episode), int(step))  # range check
        self._subs.setdefault(int(run), []).append(
            (episode, step, picture, category, position, support_accuracy)
        )

    def flush(self) -> None:
        """Close the current chunk and write it out: everything recorded so far survives a kill."""
        self._check_open()
        self._mcap.flush()
        self._since_flush = 0

    def close(self, *, complete: bool = True) -> Path:
        """Finish the MCAP file (summary and index) and rename it to its final name; with
        ``complete=False`` (an interrupted run) the finished file keeps its ``.partial`` name.
        Returns the path of the file."""
        if not self._closed:
            self._mcap.add_metadata(
                "closed",
                {
                    "complete": str(bool(complete)).lower(),
                    "episodes": str(self.n_episodes),
                    "substitutions": str(self.n_substitutions),
                },
            )
            self._mcap.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()
            self._closed = True
            if complete:
                os.replace(self.partial_path, self.path)
        return self.path if complete else self.partial_path

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"record writer for {self.path} is closed")

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(complete=exc_type is None)
