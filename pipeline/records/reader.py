"""Load MCAP records into pandas DataFrames (DESIGN.md "Records").

    recs = read_records("datasets/runs/fig8")          # a file, or a folder of .mcap files
    recs.episodes.groupby("run").collisions.sum()
    recs.steps[recs.steps.collided]

A truncated or corrupt file (a killed run's ``.mcap.partial``, a cut copy) is read up to its last
complete chunk, with a :class:`RecordsWarning` that names the file and says what was lost; a file
from which nothing at all can be read still warns, it never silently returns nothing.
Decoding is vectorised (:mod:`.decode`): a few tag reads per message (one per sink batch of
episodes), then a handful of numpy operations per column over all messages at once.
"""
from __future__ import annotations

import json
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from . import schema as S
from .decode import decode_batches, decode_batches_protobuf
from .scan import Scan, scan

STEP_COLUMNS = ("run", "episode", "step", "state", "action", "reward", "flags")


class RecordsWarning(UserWarning):
    """A record file was truncated, corrupt or unfinished; the message names the file and the loss."""


@dataclass
class FileMeta:
    """The per-file metadata of one record file."""

    path: Path
    complete: bool  # finished and renamed by RecordWriter.close()
    config: dict | None = None
    config_yaml: str | None = None
    seeds: Any = None
    versions: dict[str, str] = field(default_factory=dict)
    maze: dict[str, Any] | None = None  # layout (list of rows), width, height, categories
    obstacles: dict[int, list[dict[str, int]]] = field(default_factory=dict)  # run -> assignment
    info: dict[str, Any] = field(default_factory=dict)
    closed: dict[str, str] | None = None
    pictures: dict[int, bytes] = field(default_factory=dict)
    support_pictures: dict[tuple[int, int], bytes] = field(default_factory=dict)  # (category, position)
    problems: list[str] = field(default_factory=list)


@dataclass
class Records:
    """Everything read from one or more record files. Every frame has a categorical ``file`` column."""

    steps: pd.DataFrame
    episodes: pd.DataFrame
    recognitions: pd.DataFrame
    unsafe: pd.DataFrame
    substitutions: pd.DataFrame
    files: dict[str, FileMeta]
    q_values: dict[tuple[str, int, int], np.ndarray] = field(default_factory=dict)

    @property
    def meta(self) -> FileMeta:
        """The metadata of the only file read (error when several were)."""
        if len(self.files) != 1:
            raise ValueError(f"records of {len(self.files)} files: pick one of records.files[...]")
        return next(iter(self.files.values()))


def find_record_files(folder: str | Path) -> list[Path]:
    """Every ``*.mcap`` under ``folder`` (recursively), plus ``*.mcap.partial`` files of killed runs
    that have no finished counterpart, sorted."""
    folder = Path(folder)
    finished = sorted(folder.rglob("*.mcap"))
    names = {p for p in finished}
    partial = [p for p in sorted(folder.rglob("*.mcap.partial")) if p.with_name(p.name[:-8]) not in names]
    return sorted(finished + partial)


def read_records(path: str | Path | Iterable[str | Path], *, run: int | None = None,
                 episode: int | None = None, pictures: bool = True) -> Records:
    """Read one record file, a folder of them, or a list of files into :class:`Records`.

    ``run`` / ``episode`` restrict the result to one run (and episode); chunks outside it are not
    decompressed, so replaying one episode of a big file is quick.
    """
    if isinstance(path, (str, Path)):
        p = Path(path)
        if p.is_dir():
            paths = find_record_files(p)
            if not paths:
                raise FileNotFoundError(f"no .mcap record files under {p}")
        elif p.exists():
            paths = [p]
        else:
            raise FileNotFoundError(f"record file {p} does not exist")
    else:
        paths = [Path(x) for x in path]
    paths = list(dict.fromkeys(paths))
    time_range = None
    if run is not None:
        if episode is None:
            time_range = (S.log_time_ns(run, 0), S.log_time_ns(run + 1, 0))
        else:
            time_range = (S.log_time_ns(run, episode), S.log_time_ns(run, episode + 1))
    parts = [_read_file(p, time_range, pictures) for p in paths]
    return _combine(parts)


# ---------------------------------------------------------------------------------------------
def _i(values, dtype) -> np.ndarray:
    return np.array(values, dtype=dtype)


def _step_index(lengths: np.ndarray) -> np.ndarray:
    """0..n-1 within each episode, for concatenated episodes of the given lengths."""
    total = int(lengths.sum())
    starts = np.cumsum(lengths) - lengths
    return (np.arange(total, dtype=np.int64) - np.repeat(starts, lengths)).astype(np.int32)


def _decode_batches(messages: list[tuple[int, bytes]], name: str) -> dict[str, Any]:
    """Columns of the EpisodeBatch messages: vectorised (:mod:`.decode`), or through the Protobuf
    runtime when a message has a shape the fast path does not handle."""
    data = [d for _, d in messages]
    flat = decode_batches(data)
    out = _columns(flat, name) if flat is not None else None
    return out if out is not None else _columns(decode_batches_protobuf(data), name, strict=True)


class _Inconsistent(ValueError):
    pass


def _columns(d: dict[str, Any], name: str, strict: bool = False) -> dict[str, Any] | None:
    """The frames' columns from the flat columns of :mod:`.decode` (None, or with ``strict`` an
    error naming the problem, when the messages' arrays do not fit together)."""
    c = d["counts"]

    def bad(why: str):
        if strict:
            raise _Inconsistent(f"{name}: episode batch messages are inconsistent: {why}")
        return None

    n_eps = c["episode"]
    for k in ("s_steps", "s_collisions", "s_return", "s_reached_goal", "s_prevented", "s_epsilon",
              "s_greedy_optimal"):
        if not np.array_equal(c[k], n_eps):
            return bad(f"summary column {k[2:]} does not have one entry per episode")
    lens = d["s_steps"]
    msg_steps = np.bincount(np.repeat(np.arange(len(n_eps)), n_eps), weights=lens,
                            minlength=len(n_eps)).astype(np.int64)
    for k in ("states", "actions", "rewards", "flags"):
        if not np.array_equal(c[k], msg_steps):
            return bad(f"step column {k} does not have the episodes' step count")
    rec_m, un_k = c["r_episode"], c["u_episode"]
    if any(not np.array_equal(c[k], rec_m) for k in ("r_step", "r_state", "r_action", "r_picture",
                                                       "r_predicted", "r_true")):
        return bad("recognition columns differ in length")
    if any(not np.array_equal(c[k], un_k) for k in ("u_step", "u_state", "u_action", "u_source")):
        return bad("unsafe-set columns differ in length")
    ncat = d["n_categories"]
    if not np.array_equal(c["scores"], np.where(c["scores"] > 0, rec_m * ncat, 0)):
        return bad("scores do not have n_categories columns")
    ep_run = np.repeat(d["run"], n_eps).astype(np.int32)
    ep_ep = d["episode"].astype(np.int32)
    ep_key = ep_run.astype(np.int64) << 32 | ep_ep
    flags_a = d["flags"].astype(np.uint8)
    steps = {"run": np.repeat(ep_run, lens), "episode": np.repeat(ep_ep, lens), "step": _step_index(lens),
             "state": d["states"].astype(np.int32), "action": d["actions"].astype(np.int8),
             "reward": d["rewards"].astype(np.float32), "flags": flags_a}
    for flag_name, bit in S.FLAG_NAMES.items():
        steps[flag_name] = (flags_a & bit) != 0
    rec = {"run": np.repeat(d["run"], rec_m).astype(np.int32), "episode": d["r_episode"].astype(np.int32),
           "step": d["r_step"].astype(np.int32), "state": d["r_state"].astype(np.int32),
           "action": d["r_action"].astype(np.int8), "picture": d["r_picture"].astype(np.int16),
           "predicted": d["r_predicted"].astype(np.int8), "true": d["r_true"].astype(np.int8)}
    rec["correct"] = rec["predicted"] == rec["true"]
    n_rec = len(rec["step"])
    has_scores = c["scores"] > 0
    width = int(ncat[has_scores].max()) if has_scores.any() else 0
    if width:
        if has_scores[rec_m > 0].all() and (ncat[has_scores] == width).all():
            scores = d["scores"].astype(np.float32).reshape(n_rec, width)
        else:  # some batches without scores (or fewer columns): NaN there
            scores = np.full((n_rec, width), np.nan, dtype=np.float32)
            row, pos = 0, 0
            for m, k, has in zip(rec_m, ncat, has_scores):
                if has:
                    scores[row:row + m, :k] = d["scores"][pos:pos + m * k].reshape(m, k)
                    pos += m * k
                row += m
        for j in range(width):
            rec[f"score_{j}"] = scores[:, j]
    unsafe = {"run": np.repeat(d["run"], un_k).astype(np.int32), "episode": d["u_episode"].astype(np.int32),
              "step": d["u_step"].astype(np.int32), "state": d["u_state"].astype(np.int32),
              "action": d["u_action"].astype(np.int8), "source": d["u_source"].astype(np.int8)}
    per_episode = {}
    order = np.argsort(ep_key, kind="stable")
    sorted_keys = ep_key[order]
    for what, cols in (("recognitions", rec), ("unsafe", unsafe)):
        key = cols["run"].astype(np.int64) << 32 | cols["episode"]
        pos = np.searchsorted(sorted_keys, key)
        if len(key) and (pos.max() >= len(sorted_keys) or not np.array_equal(sorted_keys[pos], key)):
            return bad(f"{what} of episodes that are not in their batch")
        per_episode[what] = np.bincount(order[pos], minlength=len(ep_key)).astype(np.int32)
    episodes = {"run": ep_run, "episode": ep_ep, "steps": lens.astype(np.int32),
                "collisions": d["s_collisions"].astype(np.int32), "return_": d["s_return"].astype(np.float64),
                "reached_goal": d["s_reached_goal"] != 0, "prevented": d["s_prevented"].astype(np.int32),
                "epsilon": d["s_epsilon"].astype(np.float64), "greedy_optimal": d["s_greedy_optimal"] != 0,
                "n_recognitions": per_episode["recognitions"], "n_unsafe_added": per_episode["unsafe"]}
    q_values = {}
    if c["q_values"].any():
        pos, row = 0, 0
        for i, (cnt, na, e) in enumerate(zip(c["q_values"], d["n_actions"], n_eps)):
            if cnt:
                if not na or cnt % (na * e):
                    return bad("q_values do not have n_actions columns for every episode")
                tables = d["q_values"][pos:pos + cnt].astype(np.float32).reshape(e, -1, int(na))
                for j in range(e):
                    q_values[(name, int(ep_run[row + j]), int(ep_ep[row + j]))] = tables[j]
                pos += cnt
            row += e
    return {"steps": steps, "recognitions": rec, "unsafe": unsafe, "episodes": episodes, "q_values": q_values}


def _decode_substitutions(messages: list[tuple[int, bytes]]) -> dict[str, np.ndarray]:
    cols = {k: [] for k in ("run", "episode", "step", "picture", "category", "position", "support_accuracy")}
    for _, data in messages:
        m = S.Substitution.FromString(data)
        for k, col in cols.items():
            col.append(getattr(m, k))
    types = {"run": np.int32, "episode": np.int32, "step": np.int32, "picture": np.int16,
             "category": np.int8, "position": np.int8, "support_accuracy": np.float64}
    return {k: _i(v, types[k]) for k, v in cols.items()}


def _file_meta(sc: Scan, pictures: bool) -> FileMeta:
    md = sc.metadata
    meta = FileMeta(path=sc.path, complete=sc.complete and not sc.path.name.endswith(".partial"))
    if "config" in md:
        meta.config_yaml = md["config"].get("yaml")
        meta.config = json.loads(md["config"]["json"]) if "json" in md["config"] else None
    if "seeds" in md:
        meta.seeds = json.loads(md["seeds"]["json"])
    meta.versions = dict(md.get("versions", {}))
    if "maze" in md:
        mz = md["maze"]
        meta.maze = {"layout": mz["layout"].split("\n"), "width": int(mz["width"]), "height": int(mz["height"]),
                     "categories": json.loads(mz["categories"]) if "categories" in mz else None}
        if "extra" in mz:
            meta.maze.update(json.loads(mz["extra"]))
    if "obstacles" in md:
        meta.obstacles = {int(k): v for k, v in json.loads(md["obstacles"]["json"]).items()}
    meta.info = {k: json.loads(v) for k, v in md.get("info", {}).items()}
    meta.closed = md.get("closed")
    if pictures:
        for topic, msgs in sc.messages.items():
            if topic.startswith(S.TOPIC_PICTURES + "/"):
                meta.pictures[int(topic.rsplit("/", 1)[1])] = S.CompressedImage.FromString(msgs[-1][1]).data
            elif topic.startswith(S.TOPIC_SUPPORT + "/"):
                _, _, cat, pos = topic.split("/")
                meta.support_pictures[(int(cat), int(pos))] = S.CompressedImage.FromString(msgs[-1][1]).data
    return meta


def _check_format(sc: Scan) -> None:
    """Refuse a file whose episodes channel holds another message type than ours (an older format)."""
    for ch in sc.channels.values():
        if ch.topic == S.TOPIC_EPISODES:
            schema = sc.schemas.get(ch.schema_id)
            got = schema.name if schema is not None else "?"
            if got != S.EpisodeBatch.DESCRIPTOR.full_name:
                raise ValueError(f"{sc.path}: its {S.TOPIC_EPISODES} channel holds {got} messages; this "
                                 f"reader reads {S.EpisodeBatch.DESCRIPTOR.full_name} (record format "
                                 f"{S.FORMAT_VERSION}): re-run the trials that wrote it")


def _read_file(path: Path, time_range, pictures: bool) -> dict[str, Any]:
    # An EpisodeBatch is stamped at its first episode, so one stamped before the requested
    # episodes of the run may hold them: scan from the run's start, then filter rows.
    scan_range = None if time_range is None else (S.log_time_ns(S.split_log_time(time_range[0])[0], 0),
                                                   time_range[1])
    sc = scan(path, time_range=scan_range)
    name = str(path)
    ep_msgs = sc.messages.get(S.TOPIC_EPISODES, [])
    _check_format(sc)
    try:
        dec = _decode_batches(ep_msgs, name)
    except Exception as e:  # a message that passed the chunk CRC but does not parse: keep the rest
        good = []
        for t, data in ep_msgs:
            try:
                _decode_batches([(t, data)], name)
                good.append((t, data))
            except Exception:
                pass
        sc.problems.append(f"{len(ep_msgs) - len(good)} episode batch messages did not decode "
                           f"({type(e).__name__}: {e})")
        dec = _decode_batches(good, name)
    dec["substitutions"] = _decode_substitutions(sc.messages.get(S.TOPIC_SUBSTITUTIONS, []))
    meta = _file_meta(sc, pictures)
    n_ep = len(dec["episodes"]["run"])
    problems = list(sc.problems)
    if path.name.endswith(".partial") and not problems:
        if meta.closed is None:
            problems.append("this is an unfinished recording (.partial) without its closing record")
        else:
            problems.append("this recording was closed after an error (.partial): its runs stopped early")
    if meta.closed is None and sc.complete and not path.name.endswith(".partial"):
        problems.append("the file has no closing record: it was not finished by RecordWriter.close()")
    if problems:
        if n_ep:
            runs, eps = dec["episodes"]["run"], dec["episodes"]["episode"]
            last = int(np.argmax(runs.astype(np.int64) * S.RUN_NS + eps))
            kept = (f"kept {n_ep} complete episodes (up to run {int(runs[last])} episode {int(eps[last])}) "
                    f"and {len(dec['substitutions']['run'])} substitutions")
        else:
            kept = "no complete episode could be read"
        warnings.warn(f"{path}: " + "; ".join(problems) + f"; {kept}", RecordsWarning, stacklevel=3)
    elif n_ep == 0 and time_range is None:
        warnings.warn(f"{path}: the file holds no episode records", RecordsWarning, stacklevel=3)
    if time_range is not None:
        dec = _filter_time(dec, time_range)
    meta.problems = problems
    dec["meta"] = meta
    return dec


def _filter_time(dec: dict[str, Any], time_range) -> dict[str, Any]:
    """Keep rows whose (run, episode) lies in ``time_range`` (episode messages are stamped at step 0)."""
    lo, hi = time_range
    for key in ("steps", "recognitions", "unsafe", "episodes", "substitutions"):
        cols = dec[key]
        t = cols["run"].astype(np.int64) * S.RUN_NS + cols["episode"].astype(np.int64) * S.EPISODE_NS
        keep = (t >= lo) & (t < hi)
        if not keep.all():
            dec[key] = {k: v[keep] for k, v in cols.items()}
    return dec


def _frame(cols: dict[str, np.ndarray], file_codes: np.ndarray, files: list[str]) -> pd.DataFrame:
    """A DataFrame sorted by (file, run, episode, step), with a categorical ``file`` column."""
    key = cols["run"].astype(np.int64) * S.RUN_NS + cols["episode"].astype(np.int64) * S.EPISODE_NS
    if "step" in cols:
        key = key + cols["step"].astype(np.int64) * S.STEP_NS
    dk, df_ = np.diff(key), np.diff(file_codes)
    if not ((df_ > 0) | ((df_ == 0) & (dk >= 0))).all():
        order = np.lexsort((key, file_codes))
        cols = {k: v[order] for k, v in cols.items()}
        file_codes = file_codes[order]
    df = pd.DataFrame(cols)
    df.insert(0, "file", pd.Categorical.from_codes(file_codes, categories=files))
    return df


def _combine(parts: list[dict[str, Any]]) -> Records:
    files = [str(p["meta"].path) for p in parts]
    frames = {}
    for key in ("steps", "episodes", "recognitions", "unsafe", "substitutions"):
        cols_list = [p[key] for p in parts]
        names: list[str] = []
        for c in cols_list:
            names += [n for n in c if n not in names]
        lengths = [len(c["run"]) for c in cols_list]
        codes = np.repeat(np.arange(len(parts), dtype=np.int32), lengths)
        merged = {}
        for n in names:
            arrays = []
            for c, m in zip(cols_list, lengths):
                if n in c:
                    arrays.append(c[n])
                else:  # a column another file has (an extra summary key, more score columns)
                    arrays.append(np.full(m, np.nan, dtype=np.float64))
            merged[n] = np.concatenate(arrays) if arrays else np.array([])
        frames[key] = _frame(merged, codes, files)
    q_values = {}
    for p in parts:
        q_values.update(p["q_values"])
    return Records(steps=frames["steps"], episodes=frames["episodes"], recognitions=frames["recognitions"],
                   unsafe=frames["unsafe"], substitutions=frames["substitutions"],
                   files={str(p["meta"].path): p["meta"] for p in parts}, q_values=q_values)
