"""Load MCAP records into pandas DataFrames (DESIGN.md "Records").

    recs = read_records("datasets/runs/fig8")          # a file, or a folder of .mcap files
    recs.episodes.groupby("run").collisions.sum()
    recs.steps[recs.steps.collided]

A damaged or truncated file loses only what its damaged parts held (:mod:`.scan` resynchronises
after a bad chunk or record); a :class:`RecordsWarning` names the file and says what was lost, in
runs and episodes, counted from what its metadata says it should hold (:mod:`.loss`). A file with
nothing to read (empty, not MCAP, another program's MCAP) raises :class:`RecordsError`, a
:class:`~pipeline.errors.UserError`. Nothing is dropped silently.
Decoding (:mod:`.codec`): the Protobuf runtime with raw-view classes, one ``np.frombuffer`` per
column; a file of an older format is decoded with its own schema.
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
from .codec import FormatError, decode_batches, decode_substitutions
from .loss import account, damaged, expected_shape
from .scan import Damage, RecordsError, Scan, message_kind, scan

STEP_COLUMNS = ("run", "episode", "step", "state", "action", "reward", "flags")


class RecordsWarning(UserWarning):
    """A record file was truncated, corrupt or unfinished; the message names the file and the loss."""


class RecordsNotFound(RecordsError, FileNotFoundError):
    """No such record file, or no record file under a folder."""


@dataclass
class FileMeta:
    """The per-file metadata of one record file."""

    path: Path
    complete: bool  # finished and renamed by RecordWriter.close(), and nothing in it is damaged or missing
    config: dict | None = None
    config_yaml: str | None = None
    seeds: Any = None
    versions: dict[str, str] = field(default_factory=dict)
    maze: dict[str, Any] | None = None  # layout (list of rows), width, height, categories, actions, moves
    obstacles: dict[int, list[dict[str, int]]] = field(default_factory=dict)  # run -> assignment
    info: dict[str, Any] = field(default_factory=dict)
    closed: dict[str, str] | None = None
    pictures: dict[int, bytes] = field(default_factory=dict)
    support_pictures: dict[tuple[int, int], bytes] = field(default_factory=dict)  # (category, position)
    problems: list[str] = field(default_factory=list)  # what the warning said, one sentence each
    partial: bool = False  # a ``.partial`` file: a killed or interrupted run
    damaged: bool = False  # some of its bytes are wrong (not only cut short)
    expected_episodes: int | None = None  # what the metadata says it should hold (in the requested window)
    lost: str = ""  # short: the runs and episodes lost or missing, for a one-line listing
    readable: bool = True  # False: not one record (metadata, message) could be read

    @property
    def unusable(self) -> str | None:
        """Why nothing at all could be read from the file (None when something could)."""
        if self.readable:
            return None
        return f"{self.path}: " + ("; ".join(self.problems) or "it holds no records") + "; nothing could be read"

    @property
    def status(self) -> str:
        """``complete``, ``DAMAGED``, ``INCOMPLETE`` (cut short or unfinished), with ``PARTIAL`` for
        the ``.partial`` file of a killed or interrupted run."""
        if self.complete:
            return "complete"
        word = "DAMAGED" if self.damaged else "INCOMPLETE"
        return f"PARTIAL, {word}" if self.partial else word


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


def _finished_counterpart(p: Path) -> Path:
    """The finished file a ``.partial`` becomes: beside it, or, inside the trials stage's
    ``.staging-<pid>`` folder, at the same place outside it."""
    final = p.with_name(p.name[:-len(".partial")])
    parts = final.parts
    for i in range(len(parts) - 1, -1, -1):
        if parts[i].startswith(".staging-"):
            return Path(*parts[:i], *parts[i + 1:])
    return final


def find_record_files(folder: str | Path, *, every_partial: bool = False) -> list[Path]:
    """Every ``*.mcap`` file under ``folder`` (recursively, ``.staging-*`` folders of interrupted
    trials included), plus ``*.mcap.partial`` files of killed runs, sorted. A ``.partial`` whose
    finished counterpart exists (beside it, or outside its ``.staging-*`` folder) is left out
    unless ``every_partial``."""
    folder = Path(folder)
    finished = sorted(p for p in folder.rglob("*.mcap") if not p.is_dir())
    names = set(finished)
    partial = [p for p in sorted(folder.rglob("*.mcap.partial")) if not p.is_dir()
               and (every_partial or (_finished_counterpart(p) not in names and p.with_name(p.name[:-8]) not in names))]
    return sorted(finished + partial)


def read_records(path: str | Path | Iterable[str | Path], *, run: int | None = None,
                 episode: int | None = None, pictures: bool = True) -> Records:
    """Read one record file, a folder of them, or a list of files into :class:`Records`.

    ``run`` / ``episode`` restrict the result to one run (and episode); chunks outside it are not
    decompressed, so replaying one episode of a big file is quick.

    A file that cannot be read at all raises :class:`RecordsError` (naming it and the problem); in
    a folder such a file, and a ``.partial`` beside its finished counterpart, is skipped with a
    :class:`RecordsWarning` instead, as long as some file can be read.
    """
    folder = None
    if isinstance(path, (str, Path)):
        p = Path(path)
        if p.is_dir():
            folder = p
            paths = find_record_files(p)
            if not paths:
                raise RecordsNotFound(f"{p}: no .mcap record files under this folder")
            left_out = [q for q in find_record_files(p, every_partial=True) if q not in set(paths)]
            for q in left_out:
                warnings.warn(f"{q}: not read: an unfinished recording whose finished file "
                              f"{_finished_counterpart(q)} is there (read it by name)", RecordsWarning, stacklevel=2)
        elif p.exists():
            paths = [p]
        else:
            raise RecordsNotFound(f"{p}: no such record file")
    else:
        paths = [Path(x) for x in path]
    paths = list(dict.fromkeys(paths))
    time_range = None
    if run is not None:
        if episode is None:
            time_range = (S.log_time_ns(run, 0), S.log_time_ns(run + 1, 0))
        else:
            time_range = (S.log_time_ns(run, episode), S.log_time_ns(run, episode + 1))
    parts, bad = [], []
    for p in paths:
        try:
            parts.append(_read_file(p, time_range, pictures))
        except RecordsError as e:
            if folder is None:
                raise
            bad.append(str(e))
            warnings.warn(f"not read: {e}", RecordsWarning, stacklevel=2)
    if not parts:
        raise RecordsError(f"{folder}: no readable record file: " + "; ".join(bad))
    return _combine(parts)


# ---------------------------------------------------------------------------------------------
def _file_meta(sc: Scan, pictures: bool) -> FileMeta:
    """The file's metadata records; one that does not parse is a damaged part (named), not an error."""
    md = sc.metadata
    meta = FileMeta(path=sc.path, complete=False, partial=sc.path.name.endswith(".partial"))

    def part(name: str, fn) -> None:
        if name not in md:
            return
        try:
            fn(md[name])
        except Exception as e:
            sc.damage.append(Damage("metadata", f"metadata record '{name}' does not parse ({type(e).__name__}: {e})"))

    def config(rec):
        meta.config_yaml = rec.get("yaml")
        meta.config = json.loads(rec["json"]) if "json" in rec else None

    def seeds(rec):
        meta.seeds = json.loads(rec["json"])

    def maze(mz):
        out = {"layout": mz["layout"].split("\n"), "width": int(mz["width"]), "height": int(mz["height"]),
               "categories": json.loads(mz["categories"]) if "categories" in mz else None,
               "actions": mz["actions"].split(",") if "actions" in mz else None,  # names; older files: N,E,S,W
               "moves": [tuple(m) for m in json.loads(mz["moves"])] if "moves" in mz else None}  # older files: none
        if "extra" in mz:
            out.update(json.loads(mz["extra"]))
        meta.maze = out

    def obstacles(rec):
        meta.obstacles = {int(k): v for k, v in json.loads(rec["json"]).items()}

    def info(rec):
        meta.info = {k: json.loads(v) for k, v in rec.items()}

    part("config", config)
    part("seeds", seeds)
    meta.versions = dict(md.get("versions", {}))
    part("maze", maze)
    part("obstacles", obstacles)
    part("info", info)
    meta.closed = md.get("closed")
    if pictures:
        for topic, msgs in sc.messages.items():
            try:
                if topic.startswith(S.TOPIC_PICTURES + "/"):
                    meta.pictures[int(topic.rsplit("/", 1)[1])] = S.CompressedImage.FromString(msgs[-1][1]).data
                elif topic.startswith(S.TOPIC_SUPPORT + "/"):
                    _, _, cat, pos = topic.split("/")
                    meta.support_pictures[(int(cat), int(pos))] = S.CompressedImage.FromString(msgs[-1][1]).data
            except Exception as e:
                sc.damage.append(Damage("decode", f"the picture message on {topic} does not decode "
                                                  f"({type(e).__name__})"))
    return meta


def _check_ours(sc: Scan) -> None:
    """Refuse a file with nothing to read, another program's MCAP file, and a file whose episodes
    channel holds another message type than ours (an older format)."""
    path = sc.path
    ours = ((sc.library or "").startswith("pipeline.records/") or "recording" in sc.metadata
            or any(ch.topic == S.TOPIC_EPISODES for ch in sc.channels.values()))
    if not sc.metadata and not sc.messages:
        return  # our magic bytes and nothing after them that can be read (a cut copy, a killed run)
    if not ours:
        lib = f"by {sc.library!r}" if sc.library else "by another program"
        topics = sorted({ch.topic for ch in sc.channels.values()})
        held = f" (channels {', '.join(topics[:4])}{', ...' if len(topics) > 4 else ''})" if topics else ""
        raise RecordsError(f"{path}: not a record file of this pipeline: an MCAP file written {lib}{held}, "
                           f"without the 'recording' metadata or an {S.TOPIC_EPISODES} channel")
    for ch in sc.channels.values():
        if ch.topic == S.TOPIC_EPISODES:
            schema = sc.schemas.get(ch.schema_id)
            got = schema.name if schema is not None else "?"
            if got != S.EpisodeBatch.DESCRIPTOR.full_name:
                raise RecordsError(f"{path}: its {S.TOPIC_EPISODES} channel holds {got} messages; this "
                                   f"reader reads {S.EpisodeBatch.DESCRIPTOR.full_name} (record format "
                                   f"{S.FORMAT_VERSION}): re-run the trials that wrote it")


def _message_counts(sc: Scan, meta: FileMeta, dec: dict[str, Any]) -> dict[str, tuple[int, int]]:
    """kind -> (read, expected) messages of the kinds the episode ranges do not show: from the
    summary's statistics; without them, from the message index records of the lost chunks (and the
    closing record's substitution count)."""
    read_by_kind: dict[str, int] = {}
    for topic, msgs in sc.messages.items():
        kind = message_kind(topic)
        if kind and kind != "episode batches":
            read_by_kind[kind] = read_by_kind.get(kind, 0) + len(msgs)
    out: dict[str, tuple[int, int]] = {}
    stats = sc.summary.statistics if sc.summary is not None else None
    if stats is not None:
        for cid, count in stats.channel_message_counts.items():
            kind = message_kind(sc.channels[cid].topic) if cid in sc.channels else None
            if kind and kind != "episode batches":
                got, exp = out.get(kind, (read_by_kind.get(kind, 0), 0))
                out[kind] = (got, exp + count)
        return out
    for d in sc.damage:
        for kind, count in d.held.items():
            if kind != "episode batches":
                got, exp = out.get(kind, (read_by_kind.get(kind, 0), read_by_kind.get(kind, 0)))
                out[kind] = (got, exp + count)
    if meta.closed and str(meta.closed.get("substitutions", "")).isdigit():
        out["substitutions"] = (len(dec["substitutions"]["run"]), int(meta.closed["substitutions"]))
    return out


def _read_file(path: Path, time_range, pictures: bool) -> dict[str, Any]:
    # An EpisodeBatch is stamped at its first episode, so one stamped before the requested
    # episodes of the run may hold them: scan from the run's start, then filter rows.
    scan_range = None if time_range is None else (S.log_time_ns(S.split_log_time(time_range[0])[0], 0),
                                                   time_range[1])
    sc = scan(path, time_range=scan_range)
    name = str(path)
    _check_ours(sc)
    ep_msgs = sc.messages.get(S.TOPIC_EPISODES, [])
    schema = next((sc.schemas[c.schema_id].data for c in sc.channels.values()
                   if c.topic == S.TOPIC_EPISODES and c.schema_id in sc.schemas), None)
    try:
        dec = decode_batches(ep_msgs, name, schema)
    except FormatError as e:
        raise RecordsError(f"{path}: {e}") from None
    except Exception:  # a message that passed its chunk's CRC but does not parse: keep the rest
        good = []
        for t, data in ep_msgs:
            try:
                decode_batches([(t, data)], name, schema)
                good.append((t, data))
            except Exception as e:
                sc.damage.append(Damage("decode", f"the episode batch message stamped "
                                                  f"{_describe_time(t)} did not decode ({type(e).__name__}: {e})",
                                        (t, t)))
        dec = decode_batches(good, name, schema)
    dec["substitutions"], bad = decode_substitutions(sc.messages.get(S.TOPIC_SUBSTITUTIONS, []))
    if bad:
        sc.damage.append(Damage("decode", f"{bad} substitution messages did not decode"))
    meta = _file_meta(sc, pictures)
    runs, per_run = expected_shape(meta.config, meta.obstacles, meta.closed)
    batch_size = _batch_size(dec, per_run) if sc.damage else None  # before filtering: whole batches
    if time_range is not None:
        dec = _filter_time(dec, time_range)
    truncated = any(d.kind == "truncated" for d in sc.damage)
    loss = account(sc, dec["episodes"]["run"], dec["episodes"]["episode"], runs=runs, per_run=per_run,
                   batch_size=batch_size,
                   unfinished=truncated or (meta.closed or {}).get("complete") != "true",
                   window=time_range, counts=None if time_range is not None else _message_counts(sc, meta, dec))
    problems = list(loss.sentences) + list(sc.notes)
    if pictures and not meta.pictures and not meta.support_pictures and any(
            d.span is not None and d.span[0] == 0 and d.kind in ("chunk", "bytes", "truncated") and not d.index
            for d in sc.damage) and not (sc.summary is not None and sc.summary.statistics is not None):
        problems.append("no picture could be read: the file's pictures, if it had any, were in the damaged part "
                        "(they are stamped at time 0)")
    if sc.dropped:
        problems.append(f"{sc.dropped} messages referred to channels defined in lost parts and were dropped")
    if not sc.damage:
        if meta.partial:
            if meta.closed is None:
                problems.insert(0, "this is an unfinished recording (.partial) without its closing record")
            else:
                problems.insert(0, "this recording was closed after an error (.partial): its runs stopped early")
        elif meta.closed is None:
            problems.insert(0, "the file has no closing record: it was not finished by RecordWriter.close()")
        elif meta.closed.get("complete") != "true":
            problems.insert(0, "its closing record says the trials stopped early")
    n_ep = len(dec["episodes"]["run"])
    meta.expected_episodes = loss.expected
    meta.damaged = damaged(sc.damage)
    meta.lost = loss.headline
    meta.complete = sc.complete and not meta.partial and not problems
    meta.readable = bool(sc.metadata or sc.messages)
    if problems:
        of = f" of {loss.expected}" if loss.expected is not None else ""
        if n_ep:
            runs_, eps = dec["episodes"]["run"], dec["episodes"]["episode"]
            last = int(np.argmax(runs_.astype(np.int64) * S.RUN_NS + eps))
            kept = (f"kept {n_ep}{of} episodes (up to run {int(runs_[last])} episode {int(eps[last])}) "
                    f"and {len(dec['substitutions']['run'])} substitutions")
        elif meta.readable:
            kept = f"no complete episode could be read{' (' + str(loss.expected) + ' expected)' if of else ''}"
        else:
            kept = "no complete episode could be read, nor any other record"
        warnings.warn(f"{path}: " + "; ".join(problems) + f"; {kept}", RecordsWarning, stacklevel=3)
    elif n_ep == 0 and time_range is None:
        warnings.warn(f"{path}: the file holds no episode records", RecordsWarning, stacklevel=3)
    meta.problems = problems
    dec["meta"] = meta
    return dec


def _batch_size(dec: dict[str, Any], per_run: int | None) -> int | None:
    """The episodes of every sink batch read, when all are the same size (bar each run's last): the
    trials runner hands over fixed-size batches, so a lost batch holds that many episodes."""
    sizes = np.asarray(dec.get("batch_sizes", ()), dtype=np.int64)
    if not len(sizes):
        return None
    ends = np.cumsum(sizes) - 1
    last_ep = dec["episodes"]["episode"][ends] if len(dec["episodes"]["episode"]) else ends
    full = sizes[last_ep != per_run - 1] if per_run is not None else sizes
    if not len(full):
        full = sizes
    return int(full[0]) if (full == full[0]).all() else None


def _describe_time(t: int) -> str:
    r, e, _ = S.split_log_time(t)
    return f"run {r} episode {e}"


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
