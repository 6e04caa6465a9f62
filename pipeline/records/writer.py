"""The MCAP record writer: an episode sink (``pipeline/rl/sink.py``) that records every episode of
every run (DESIGN.md "Records"; schema in :mod:`pipeline.records.schema`).

    with RecordWriter("datasets/runs/fig8/fewshot.mcap", metadata={"config": cfg, "seeds": seeds},
                      maze={"layout": rows, "categories": names}, runs=assignments,
                      pictures=query_pngs) as sink:
        runner.run(sink=sink)          # calls sink.episode(**fields) and sink.substitution(...)

Finishing is atomic: the writer writes ``<name>.mcap.partial`` and renames it to ``<name>.mcap``
only when :meth:`RecordWriter.close` succeeds. It closes a chunk every ``flush_every`` episodes,
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
from . import wire as W

LIBRARY = "pipeline.records/" + S.FORMAT_VERSION
LAYOUT_CHARS = frozenset("SGX.")
OBSTACLE_KEYS = ("cell", "physical", "category", "instance", "orientation")
SUMMARY_KEYS = ("steps", "collisions", "return_", "reached_goal", "prevented", "epsilon")
EPISODE_KEYS = frozenset({"run", "episode", "states", "actions", "rewards", "flags", "recognitions",
                          "unsafe_added", "summary"})
OPTIONAL_EPISODE_KEYS = frozenset({"q_values"})
RECOGNITION_KEYS = ("step", "state", "action", "picture", "predicted", "true")
UNSAFE_KEYS = ("step", "state", "action", "source")
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
           "cell_index": "row * width + col", "actions": ",".join(S.ACTION_NAMES)}
    if maze.get("categories") is not None:
        out["categories"] = to_json(list(maze["categories"]))
    extra = {k: v for k, v in maze.items() if k not in ("layout", "categories")}
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


def _arr(fields: Mapping[str, Any], key: str, where: str, dtype, n: int | None = None) -> np.ndarray:
    try:
        a = np.asarray(fields[key])
    except KeyError:
        raise ValueError(f"{where}: missing field {key!r}") from None
    if a.ndim != 1:
        raise ValueError(f"{where}.{key}: expected a 1-D array, got shape {a.shape}")
    if n is not None and len(a) != n:
        raise ValueError(f"{where}.{key}: length {len(a)} differs from the other arrays ({n})")
    return a.astype(dtype, copy=False)


class RecordWriter:
    """Writes one MCAP file of episode records; implements the episode-sink protocol of
    ``pipeline/rl/sink.py`` (:meth:`episode`, :meth:`substitution`).

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
        self._seen: set[tuple[int, int]] = set()
        self._pending: list[tuple[int, int, Any]] = []  # (channel, log time, bytes or staged episode)

        metadata = dict(metadata or {})
        records = self._metadata_records(metadata, maze, runs)  # validate before touching the disk
        images = self._image_messages(pictures, support_pictures)

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.partial_path, "wb")
        self._mcap = Writer(self._file, chunk_size=chunk_size, compression=comp[compression])
        self._mcap.start(profile="", library=LIBRARY)
        ids = {}
        for cls in (S.Episode, S.Substitution, S.CompressedImage):
            ids[cls] = self._mcap.register_schema(name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                                                  data=S.file_descriptor_set(cls))
        self._schema_ids = ids
        self._ch_episodes = self._mcap.register_channel(S.TOPIC_EPISODES, "protobuf", ids[S.Episode])
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
    def episode(self, **fields: Any) -> None:
        """Record one finished episode (fields as documented in ``pipeline/rl/sink.py``)."""
        self._check_open()
        missing = EPISODE_KEYS - fields.keys()
        unknown = fields.keys() - EPISODE_KEYS - OPTIONAL_EPISODE_KEYS
        if missing or unknown:
            raise TypeError(f"episode record: missing fields {sorted(missing)}, unknown fields "
                            f"{sorted(unknown)} (see pipeline/rl/sink.py)")
        run, episode = int(fields["run"]), int(fields["episode"])
        where = f"episode record (run {run}, episode {episode})"
        if (run, episode) in self._seen:
            raise ValueError(f"{where}: recorded twice in {self.path}")
        t = S.log_time_ns(run, episode, 0)
        staged = stage_episode(fields)
        if staged is None:  # unusual content (extra summary keys, Q table) or bad input: checked path
            staged = encode_episode_protobuf(fields, where)
        self._pending.append((self._ch_episodes, t, staged))
        self._seen.add((run, episode))
        self.n_episodes += 1
        self._since_flush += 1
        if self._since_flush >= self.flush_every:
            self.flush()

    def substitution(self, *, run: int, episode: int, step: int, picture: int, category: int,
                     position: int) -> None:
        """Record that ``picture`` replaced shot ``position`` of class ``category`` (section 3.3)."""
        self._check_open()
        t = S.log_time_ns(int(run), int(episode), int(step))
        msg = S.Substitution(run=int(run), episode=int(episode), step=int(step), picture=int(picture),
                             category=int(category), position=int(position))
        self._pending.append((self._ch_subs, t, msg.SerializeToString()))
        self.n_substitutions += 1

    # ------------------------------------------------------------------ life cycle
    def flush(self) -> None:
        """Close the current chunk and write it out: everything recorded so far survives a kill."""
        self._check_open()
        self._write_pending()
        self._mcap.flush()
        self._since_flush = 0

    def _write_pending(self) -> None:
        """Encode the staged episodes in one vectorised batch and write every pending message in
        the order it was handed over."""
        if not self._pending:
            return
        staged = [i for i, (_, _, item) in enumerate(self._pending) if not isinstance(item, bytes)]
        encoded = encode_staged([self._pending[i][2] for i in staged])
        items = list(self._pending)
        for i, data in zip(staged, encoded):
            items[i] = (items[i][0], items[i][1], data)
        add = self._mcap.add_message
        for channel, t, data in items:
            add(channel, log_time=t, publish_time=t, data=data)
        self._pending.clear()

    def close(self, *, complete: bool = True) -> Path:
        """Finish the MCAP file (summary and index) and rename it to its final name; with
        ``complete=False`` (an interrupted run) the finished file keeps its ``.partial`` name.
        Returns the path of the file."""
        if self._closed:
            return self.path if complete else self.partial_path
        self._write_pending()
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


def normalise_episode(fields: Mapping[str, Any], where: str = "episode record") -> dict[str, Any]:
    """Check one episode's sink fields and return them as typed numpy arrays (the boundary check)."""
    states = _arr(fields, "states", where, np.int64)
    n = len(states)
    out: dict[str, Any] = {"run": int(fields["run"]), "episode": int(fields["episode"]), "states": states,
                           "actions": _arr(fields, "actions", where, np.int64, n),
                           "rewards": _arr(fields, "rewards", where, np.float32, n),
                           "flags": _arr(fields, "flags", where, np.int64, n)}
    rec = fields["recognitions"] or {}
    m = len(rec["step"]) if rec else 0
    if m:
        w = where + ".recognitions"
        for k in RECOGNITION_KEYS:
            out["rec_" + k] = _arr(rec, k, w, np.int64, m)
        scores = np.asarray(rec.get("scores", ()), dtype=np.float32)
        if scores.size:
            if scores.ndim != 2 or scores.shape[0] != m:
                raise ValueError(f"{w}.scores: expected shape ({m}, n_categories), got {scores.shape}")
        else:
            scores = np.zeros((m, 0), np.float32)
        out["rec_scores"] = scores
    un = fields["unsafe_added"] or {}
    k_un = len(un["step"]) if un else 0
    if k_un:
        w = where + ".unsafe_added"
        for k in UNSAFE_KEYS:
            out["un_" + k] = _arr(un, k, w, np.int64, k_un)
    summary = fields["summary"]
    missing = [k for k in SUMMARY_KEYS if k not in summary]
    if missing:
        raise ValueError(f"{where}.summary: missing {missing}; expected {list(SUMMARY_KEYS)}")
    sm = {"steps": int(summary["steps"]), "collisions": int(summary["collisions"]),
          "return_": float(summary["return_"]), "reached_goal": bool(summary["reached_goal"]),
          "prevented": int(summary["prevented"]), "epsilon": float(summary["epsilon"])}
    extra = {}
    for k in sorted(summary.keys() - set(SUMMARY_KEYS)):
        try:
            extra[str(k)] = float(summary[k])
        except (TypeError, ValueError):
            raise ValueError(f"{where}.summary[{k!r}]: extra summary values must be numbers, "
                             f"got {summary[k]!r}") from None
    out["summary"], out["extra"] = sm, extra
    q = fields.get("q_values")
    if q is not None:
        q = np.asarray(q, dtype=np.float32)
        if q.ndim != 2:
            raise ValueError(f"{where}.q_values: expected shape (n_states, n_actions), got {q.shape}")
        out["q_values"] = q
    return out


_N_INT_FIELDS = 13  # Steps 1, 2, 4; Recognitions 1-6; UnsafeAdditions 1-4 (in this order)


_NO_EXTRA_SIZES = [0] * 10


def stage_episode(fields: Mapping[str, Any]):
    """Copy one episode's fields into a compact staged form for :func:`encode_staged`: all its
    integer arrays concatenated (one copy), the float arrays as bytes, the summary as a tuple.
    Returns None for anything unusual (extra summary keys, a Q table, inconsistent input): the
    caller then takes the checked path, :func:`encode_episode_protobuf`."""
    try:
        rec, un, summary = fields["recognitions"], fields["unsafe_added"], fields["summary"]
        states, actions, flags = fields["states"], fields["actions"], fields["flags"]
        rewards = np.asarray(fields["rewards"], dtype="<f4")
        n = len(states)
        m = len(rec["step"]) if rec else 0
        k = len(un["step"]) if un else 0
        if (len(actions) != n or len(flags) != n or rewards.shape != (n,) or len(summary) != 6
                or "q_values" in fields):
            return None
        ncat, scores = 0, b""
        if m or k:  # rare: an episode with recognitions or unsafe-set additions
            arrays = [states, actions, flags]
            if m:
                arrays += [rec[key] for key in RECOGNITION_KEYS]
            if k:
                arrays += [un[key] for key in UNSAFE_KEYS]
            sizes = [n, n, n] + [m] * 6 + [k] * 4
            if any(len(x) != size for x, size in zip(arrays, sizes)):
                return None
            ints = np.concatenate(arrays, dtype=np.int64, casting="same_kind")
            sc = np.asarray(rec.get("scores", ()), dtype="<f4") if m else None
            if sc is not None and sc.size:
                if sc.ndim != 2 or sc.shape[0] != m:
                    return None
                ncat, scores = sc.shape[1], sc.tobytes()
        else:
            sizes = [n, n, n] + _NO_EXTRA_SIZES
            ints = np.concatenate((states, actions, flags), dtype=np.int64, casting="same_kind")
        if ints.ndim != 1:
            return None
        sm = (int(summary["steps"]), int(summary["collisions"]), float(summary["return_"]),
              int(bool(summary["reached_goal"])), int(summary["prevented"]), float(summary["epsilon"]))
        run, episode = int(fields["run"]), int(fields["episode"])
        if sm[0] < 0 or sm[1] < 0 or sm[4] < 0:
            return None
    except (KeyError, TypeError, ValueError):
        return None
    return (run, episode, ints, sizes, rewards.tobytes(), scores, ncat, sm)


def encode_staged(staged: list) -> list[bytes]:
    """Serialize staged episodes as ``fsrl.records.Episode`` messages (:mod:`.wire`): the integers
    of the whole batch are varint-encoded in one numpy pass, then cut into packed fields.
    Byte-identical to :func:`encode_episode_protobuf` (tests check)."""
    if not staged:
        return []
    ints = np.concatenate([s[2] for s in staged])
    sizes = np.array([s[3] for s in staged], dtype=np.int64).ravel()
    if ints.size and (ints & ~0x7F).any():
        payload, cum = W.varints_with_ends(ints)
        bounds = cum[np.concatenate(([0], np.cumsum(sizes)))]
    else:  # every value < 128: one byte each
        payload = ints.astype(np.uint8).tobytes()
        bounds = np.concatenate(([0], np.cumsum(sizes)))
    bounds = bounds.tolist()
    lf, uf, df, vs = W.len_field, W.uint_field, W.double_field, W.varint_small
    key_steps, key_summary = W.KEY_EPISODE_STEPS, W.KEY_EPISODE_SUMMARY
    out = []
    j = 0
    for run, episode, _, sz, rewards, scores, ncat, sm in staged:
        b0, b1, b2, b3 = bounds[j:j + 4]
        steps = lf(1, payload[b0:b1]) + lf(2, payload[b1:b2]) + lf(3, rewards) + lf(4, payload[b2:b3])
        parts = [uf(1, run), uf(2, episode), key_steps, vs(len(steps)), steps]
        if sz[3]:
            b = bounds[j + 3:j + 10]
            parts.append(lf(4, b"".join([lf(i + 1, payload[b[i]:b[i + 1]]) for i in range(6)]
                                        + [uf(7, ncat), lf(8, scores)])))
        if sz[9]:
            b = bounds[j + 9:j + 14]
            parts.append(lf(5, b"".join([lf(i + 1, payload[b[i]:b[i + 1]]) for i in range(4)])))
        j += _N_INT_FIELDS
        body = uf(1, sm[0]) + uf(2, sm[1]) + df(3, sm[2]) + uf(4, sm[3]) + uf(5, sm[4]) + df(6, sm[5])
        parts += [key_summary, vs(len(body)), body]
        out.append(b"".join(parts))
    return out


def encode_episode_wire(fields: Mapping[str, Any], where: str = "episode record") -> bytes:
    """One episode through the vectorised path (:func:`stage_episode` + :func:`encode_staged`),
    falling back to the checked Protobuf path for unusual content."""
    staged = stage_episode(fields)
    return encode_episode_protobuf(fields, where) if staged is None else encode_staged([staged])[0]


def encode_episode_protobuf(fields: Mapping[str, Any], where: str = "episode record") -> bytes:
    """Reference encoder through the Protobuf ``Message`` API (slow; the tests compare)."""
    e = normalise_episode(fields, where)
    msg = S.Episode(run=e["run"], episode=e["episode"])
    msg.steps.SetInParent()
    msg.steps.states.extend(e["states"].tolist())
    msg.steps.actions.extend(e["actions"].tolist())
    msg.steps.rewards.extend(e["rewards"].tolist())
    msg.steps.flags.extend(e["flags"].tolist())
    if "rec_step" in e:
        r = msg.recognitions
        r.step.extend(e["rec_step"].tolist())
        r.state.extend(e["rec_state"].tolist())
        r.action.extend(e["rec_action"].tolist())
        r.picture.extend(e["rec_picture"].tolist())
        r.predicted.extend(e["rec_predicted"].tolist())
        r.true_category.extend(e["rec_true"].tolist())
        if e["rec_scores"].size:
            r.n_categories = e["rec_scores"].shape[1]
            r.scores.extend(e["rec_scores"].ravel().tolist())
    if "un_step" in e:
        u = msg.unsafe_added
        for k in UNSAFE_KEYS:
            getattr(u, k).extend(e["un_" + k].tolist())
    msg.summary.SetInParent()
    for k, v in e["summary"].items():
        setattr(msg.summary, k, v)
    for k, v in e["extra"].items():
        msg.summary.extra[k] = v
    if "q_values" in e:
        msg.n_actions = e["q_values"].shape[1]
        msg.q_values.extend(e["q_values"].ravel().tolist())
    return msg.SerializeToString(deterministic=True)


encode_episode = encode_episode_wire  # the default encoder for one episode
