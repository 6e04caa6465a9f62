"""The MCAP record writer: an episode sink (``pipeline/rl/sink.py``) that records every episode of
every run (DESIGN.md "Records"; schema in :mod:`pipeline.records.schema`).

    with RecordWriter("datasets/runs/fig8/fewshot.mcap", metadata={"config": cfg, "seeds": seeds},
                      maze={"layout": rows, "categories": names}, runs=assignments,
                      pictures=query_pngs) as sink:
        run_trials(..., sink=sink)     # calls sink.episodes(**batch) and sink.substitution(...)

Finishing is atomic: the writer writes ``<name>.mcap.partial`` and renames it to ``<name>.mcap``
only when :meth:`RecordWriter.close` succeeds. Each sink batch becomes one ``EpisodeBatch`` message
(encoded per batch, :mod:`.batch`). It closes a chunk once ``flush_every`` episodes have come in,
so a killed run loses at most the episodes since its last flush, and its ``.partial`` file reads
up to there (:func:`pipeline.records.read_records`). If the ``with`` block raises, the file is
finished (a valid MCAP) but keeps its ``.partial`` name.
"""
from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from importlib import metadata as _im
from pathlib import Path
from typing import Any

import numpy as np
from mcap.writer import CompressionType, Writer

from . import schema as S
from .batch import check_batch, encode_batch, one_episode_batch

LIBRARY = "pipeline.records/" + S.FORMAT_VERSION
LAYOUT_CHARS = frozenset("SGX.")
OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
VERSION_PACKAGES = ("fewshot-safe-rl-pipeline", "numpy", "numba", "pandas", "torch", "mujoco", "mcap",
                    "mcap-protobuf-support", "protobuf", "foxglove-schemas-protobuf", "rerun-sdk",
                    "hydra-core", "omegaconf", "gymnasium")


def package_versions() -> dict[str, str]:
    """Versions of the packages that shape the results (read from installed metadata, no imports)."""
    import platform

    out = {"python": platform.python_version()}
    for name in VERSION_PACKAGES:
        try:
            out[name] = _im.version(name)
        except _im.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _plain(obj: Any) -> Any:
    """Configs (dicts, OmegaConf containers, numpy values) as plain JSON-able Python."""
    if type(obj).__module__.startswith("omegaconf"):
        from omegaconf import OmegaConf

        return OmegaConf.to_container(obj, resolve=True)
    return obj


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (set, frozenset, tuple)):
        return list(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"cannot record a {type(o).__name__} in the metadata (value {o!r})")


def to_json(obj: Any) -> str:
    return json.dumps(_plain(obj), default=_json_default, sort_keys=True, separators=(",", ":"))


def _image_format(data: bytes) -> str:
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    if data[:3] == b"\xff\xd8\xff":
        return "jpeg"
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "webp"
    raise ValueError("pictures must be PNG, JPEG or WebP bytes (Foxglove's CompressedImage formats)")


def _check_maze(maze: Mapping[str, Any]) -> dict[str, str]:
    if "layout" not in maze:
        raise ValueError("maze: missing key 'layout' (list of row strings of 'S', 'G', 'X', '.')")
    rows = list(maze["layout"])
    if not rows or any(len(r) != len(rows[0]) for r in rows):
        raise ValueError(f"maze.layout: rows must be non-empty and of equal length, got {rows!r}")
    bad = set("".join(rows)) - LAYOUT_CHARS
    if bad:
        raise ValueError(f"maze.layout: unknown cell characters {sorted(bad)}; allowed: 'S', 'G', 'X', '.'")
    out = {"layout": "\n".join(rows), "height": str(len(rows)), "width": str(len(rows[0])),
           "cell_index": "row * width + col"}
    if maze.get("categories") is not None:
        out["categories"] = to_json(list(maze["categories"]))
    names, moves = maze.get("actions"), maze.get("moves")  # the caller's: records has no moves of its own
    if names is not None:  # comma-separated, as files have always had them
        if not (names := [str(n) for n in names]) or not all(names) or "," in "".join(names):
            raise ValueError(f"maze.actions: names must be non-empty and without commas, got {names!r}")
        out["actions"] = ",".join(names)
    if moves is not None:
        m = np.asarray(moves)
        if m.ndim != 2 or m.shape[1] != 2 or m.dtype.kind not in "iu" or len(names or m) != len(m):
            raise ValueError(f"maze.moves: one (d_row, d_col) pair of integers per action name, got {moves!r}")
        out["moves"] = to_json(m)
    extra = {k: v for k, v in maze.items() if k not in ("layout", "categories", "actions", "moves")}
    if extra:
        out["extra"] = to_json(extra)
    return out


def _check_runs(runs: Sequence | Mapping | None) -> dict[str, list[dict[str, int]]]:
    if runs is None:
        return {}
    items = runs.items() if isinstance(runs, Mapping) else enumerate(runs)
    out: dict[str, list[dict[str, int]]] = {}
    for run, obstacles in items:
        rows = []
        for i, ob in enumerate(obstacles):
            missing = [k for k in OBSTACLE_KEYS if k not in ob]
            if missing:
                raise ValueError(f"runs[{run}][{i}]: obstacle assignment lacks {missing}; "
                                 f"expected keys {list(OBSTACLE_KEYS)}")
            rows.append({k: int(ob[k]) for k in OBSTACLE_KEYS})
        out[str(int(run))] = rows
    return out


class RecordWriter:
    """Writes one MCAP file of episode records; implements the episode-sink protocol of
    ``pipeline/rl/sink.py`` (:meth:`episodes`, :meth:`substitution`; :meth:`episode` records one
    episode as a batch of one).

    Args:
        path: final file name (``.mcap``); written as ``<path>.partial`` until :meth:`close`.
        metadata: ``config`` (dict, OmegaConf or YAML/JSON string), ``seeds``, ``versions``
            (merged over the installed package versions) and any other JSON-able keys (``info``).
        maze: ``layout`` (rows of ``S``/``G``/``X``/``.``; cell = row * width + col), optional
            ``categories`` (names by category index) and other keys.
        runs: per-run obstacle assignment, a list (index = run) or dict run -> list of
            ``{cell, physical, category, instance, orientation}``.
        pictures: query picture id -> PNG/JPEG bytes, recorded once as ``foxglove.CompressedImage``.
        support_pictures: category -> list of K thumbnails of the initial support set (optional).
        flush_every: close a chunk every this many episodes (what a killed run may lose).
        compression: ``"zstd"``, ``"lz4"`` or ``"none"``.
    """

    def __init__(self, path: str | os.PathLike, *, metadata: Mapping[str, Any] | None = None,
                 maze: Mapping[str, Any] | None = None, runs: Sequence | Mapping | None = None,
                 pictures: Mapping[int, bytes] | None = None,
                 support_pictures: Mapping[int, Sequence[bytes]] | None = None,
                 flush_every: int = 100, compression: str = "zstd", chunk_size: int = 8 * 2**20):
        self.path = Path(path)
        if self.path.suffix != ".mcap":
            raise ValueError(f"record file name must end in .mcap, got {self.path}")
        if flush_every < 1:
            raise ValueError(f"flush_every must be >= 1, got {flush_every}")
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
        if compression not in comp:
            raise ValueError(f"compression must be one of {sorted(comp)}, got {compression!r}")
        self.partial_path = self.path.with_name(self.path.name + ".partial")
        self.flush_every = int(flush_every)
        self.n_episodes = 0
        self.n_substitutions = 0
        self._since_flush = 0
        self._closed = False
        self._next_episode: dict[int, int] = {}  # run -> first episode not yet recorded

        metadata = dict(metadata or {})
        records = self._metadata_records(metadata, maze, runs)  # validate before touching the disk
        images = self._image_messages(pictures, support_pictures)

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.partial_path, "wb")
        # enable_data_crcs: the data-end record carries a CRC of the whole data section, so a flipped
        # byte outside the chunks (the header, a metadata record, a message index) of a finished file
        # is detected too; the chunks and the summary have their own CRCs (docs/reliability.md)
        self._mcap = Writer(self._file, chunk_size=chunk_size, compression=comp[compression], enable_data_crcs=True)
        self._mcap.start(profile="", library=LIBRARY)
        ids = {}
        for cls in (S.EpisodeBatch, S.Substitution, S.CompressedImage):
            ids[cls] = self._mcap.register_schema(name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                                                  data=S.file_descriptor_set(cls))
        self._schema_ids = ids
        self._ch_episodes = self._mcap.register_channel(S.TOPIC_EPISODES, "protobuf", ids[S.EpisodeBatch])
        self._ch_subs = self._mcap.register_channel(S.TOPIC_SUBSTITUTIONS, "protobuf", ids[S.Substitution])
        for name, data in records:
            self._mcap.add_metadata(name, data)
        for topic, data in images:
            ch = self._mcap.register_channel(topic, "protobuf", ids[S.CompressedImage])
            self._mcap.add_message(ch, log_time=0, publish_time=0, data=data)
        self._mcap.flush()  # the pictures and channel definitions in a complete first chunk

    # ------------------------------------------------------------------ metadata
    @staticmethod
    def _metadata_records(metadata: dict[str, Any], maze, runs) -> list[tuple[str, dict[str, str]]]:
        import yaml

        out: list[tuple[str, dict[str, str]]] = [("recording", {
            "format_version": S.FORMAT_VERSION, "library": LIBRARY,
            "time": "log_time_ns = run * 1e15 + episode * 1e9 + step * 1e6 (1 ms a step, 1 s an episode)",
            "episodes_topic": S.TOPIC_EPISODES, "substitutions_topic": S.TOPIC_SUBSTITUTIONS,
            "pictures_topic": S.TOPIC_PICTURES + "/<picture id>"})]
        config = metadata.pop("config", None)
        if config is not None:
            config = _plain(config)
            if isinstance(config, str):
                text = config
                parsed = yaml.safe_load(text)
            else:
                parsed = json.loads(to_json(config))
                text = yaml.safe_dump(parsed, sort_keys=True)
            out.append(("config", {"yaml": text, "json": to_json(parsed)}))
        if "seeds" in metadata:
            out.append(("seeds", {"json": to_json(metadata.pop("seeds"))}))
        versions = package_versions()
        versions.update({str(k): str(v) for k, v in dict(metadata.pop("versions", {}) or {}).items()})
        out.append(("versions", versions))
        if maze is not None:
            out.append(("maze", _check_maze(maze)))
        if runs is not None:
            out.append(("obstacles", {"json": to_json(_check_runs(runs)),
                                      "keys": ",".join(OBSTACLE_KEYS)}))
        if metadata:
            out.append(("info", {str(k): to_json(v) for k, v in sorted(metadata.items())}))
        return out

    @staticmethod
    def _image_messages(pictures, support_pictures) -> list[tuple[str, bytes]]:
        out = []
        for pid in sorted(pictures or {}):
            data = bytes(pictures[pid])
            msg = S.CompressedImage(frame_id=f"picture_{int(pid)}", data=data, format=_image_format(data))
            out.append((f"{S.TOPIC_PICTURES}/{int(pid)}", msg.SerializeToString()))
        for cat in sorted(support_pictures or {}):
            for pos, data in enumerate(support_pictures[cat]):
                data = bytes(data)
                msg = S.CompressedImage(frame_id=f"support_{int(cat)}_{pos}", data=data,
                                        format=_image_format(data))
                out.append((f"{S.TOPIC_SUPPORT}/{int(cat)}/{pos}", msg.SerializeToString()))
        return out

    # ------------------------------------------------------------------ the sink protocol
    def episodes(self, **batch: Any) -> None:
        """Record a batch of consecutive finished episodes of one run (columnar fields as
        documented in ``pipeline/rl/sink.py``) as ONE ``EpisodeBatch`` message."""
        self._check_open()
        b = check_batch(batch)
        if not b["n_episodes"]:
            return
        run, first, last = b["run"], int(b["episode"][0]), int(b["episode"][-1])
        if first < self._next_episode.get(run, 0):
            raise ValueError(f"episode batch of run {run}, episodes {first}..{last}: episodes of a run must "
                             f"be recorded once and in order; {self.path} already has run {run} up to "
                             f"episode {self._next_episode[run] - 1}")
        t = S.log_time_ns(run, first, 0)
        S.log_time_ns(run, last, 0)  # range check of the last episode too
        self._mcap.add_message(self._ch_episodes, log_time=t, publish_time=t, data=encode_batch(b))
        self._next_episode[run] = last + 1
        self.n_episodes += b["n_episodes"]
        self._since_flush += b["n_episodes"]
        if self._since_flush >= self.flush_every:
            self.flush()

    def episode(self, **fields: Any) -> None:
        """Record one episode (``split_batch``'s per-episode fields): a batch of one."""
        self.episodes(**one_episode_batch(fields))

    def substitution(self, *, run: int, episode: int, step: int, picture: int, category: int,
                     position: int, support_accuracy: float = float("nan")) -> None:
        """Record that ``picture`` replaced shot ``position`` of class ``category`` (section 3.3),
        and the accuracy of the support set on the query pictures after it. ``picture = -1``
        (position -1) records the support set a run starts with."""
        self._check_open()
        t = S.log_time_ns(int(run), int(episode), int(step))
        msg = S.Substitution(run=int(run), episode=int(episode), step=int(step), picture=int(picture),
                             category=int(category), position=int(position),
                             support_accuracy=float(support_accuracy))
        self._mcap.add_message(self._ch_subs, log_time=t, publish_time=t, data=msg.SerializeToString())
        self.n_substitutions += 1

    # ------------------------------------------------------------------ life cycle
    def flush(self) -> None:
        """Close the current chunk and write it out: everything recorded so far survives a kill."""
        self._check_open()
        self._mcap.flush()
        self._since_flush = 0

    def close(self, *, complete: bool = True) -> Path:
        """Finish the MCAP file (summary and index) and rename it to its final name; with
        ``complete=False`` (an interrupted run) the finished file keeps its ``.partial`` name.
        Returns the path of the file."""
        if self._closed:
            return self.path if complete else self.partial_path
        self._mcap.add_metadata("closed", {"complete": str(bool(complete)).lower(),
                                           "episodes": str(self.n_episodes),
                                           "substitutions": str(self.n_substitutions)})
        self._mcap.finish()
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()
        self._closed = True
        if complete:
            os.replace(self.partial_path, self.path)
            return self.path
        return self.partial_path

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"record writer for {self.path} is closed")

    def __enter__(self) -> "RecordWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(complete=exc_type is None)
