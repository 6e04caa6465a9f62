"""Load MCAP records into pandas DataFrames (docs/records.md):
``read_records("datasets/runs/fig8").episodes``.

A damaged or truncated file keeps what its intact parts hold (:mod:`.scan`), with one
:class:`RecordsWarning` naming the file and what was lost (:mod:`.loss`); a file with nothing to
read raises :class:`RecordsError`.
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
from .codec import FormatError, check_schema, decode_batches
from .loss import account, describe, expected_shape
from .scan import RecordsError, Scan, scan

_FRAMES = ("steps", "episodes", "recognitions", "unsafe", "substitutions")
_UNFINISHED = {  # why an undamaged file is not complete, by (.partial, without a closing record)
    (True, True): "this is an unfinished recording (.partial) without its closing record",
    (True, False): "this recording was closed after an error (.partial): its runs stopped early",
    (False, True): "the file has no closing record: it was not finished by RecordWriter.close()",
    (False, False): "its closing record says the trials stopped early",
}


class RecordsWarning(UserWarning):
    """A record file was truncated, corrupt or unfinished; the message names the file and the loss."""


class RecordsNotFound(RecordsError, FileNotFoundError):
    """No such record file, or no record file under a folder."""


@dataclass
class FileMeta:
    """The per-file metadata of one record file."""

    path: Path
    complete: bool = False  # finished by RecordWriter.close(), nothing damaged or missing
    config: dict | None = None
    config_yaml: str | None = None
    seeds: Any = None
    versions: dict[str, str] = field(default_factory=dict)
    maze: dict[str, Any] | None = None  # layout (rows), width, height, categories, actions, moves
    obstacles: dict[int, list[dict[str, int]]] = field(default_factory=dict)  # run -> placement
    info: dict[str, Any] = field(default_factory=dict)
    closed: dict[str, str] | None = None
    record: str = "steps"  # "steps" (every step) or "episodes" (no step rows)
    pictures: dict[int, bytes] = field(default_factory=dict)
    support_pictures: dict[tuple[int, int], bytes] = field(default_factory=dict)  # (cat, pos)
    problems: list[str] = field(default_factory=list)  # the warning's sentences
    partial: bool = False  # a ``.partial`` file: a killed or interrupted run
    damaged: bool = False  # some of its bytes are wrong (not only cut short)
    expected_runs: int | None = None  # what the metadata says it should hold
    expected_episodes: int | None = None  # the same, in the requested window
    lost: str = ""  # short: the runs and episodes lost or missing, for a one-line listing
    readable: bool = True  # False: not one record (metadata, message) could be read

    @property
    def unusable(self) -> str | None:
        """Why nothing at all could be read from the file (None when something could)."""
        why = "; ".join(self.problems) or "it holds no records"
        return None if self.readable else f"{self.path}: {why}; nothing could be read"

    @property
    def status(self) -> str:
        """``complete``, ``DAMAGED`` or ``INCOMPLETE``; ``PARTIAL, ...`` for a ``.partial``."""
        word = "complete" if self.complete else "DAMAGED" if self.damaged else "INCOMPLETE"
        return f"PARTIAL, {word}" if self.partial and not self.complete else word


@dataclass
class Records:
    """Everything read from one or more record files. Every frame has a categorical ``file``."""

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


def _finished(p: Path) -> Path:
    """What a ``.partial`` becomes: beside it or, in a ``.staging-<pid>`` folder, outside that."""
    parts = p.with_name(p.name[: -len(".partial")]).parts
    staging = [i for i, part in enumerate(parts) if part.startswith(".staging-")]
    return Path(*parts[: staging[-1]], *parts[staging[-1] + 1 :]) if staging else Path(*parts)


def find_record_files(folder: str | Path, *, every_partial: bool = False) -> list[Path]:
    """Every ``*.mcap`` under ``folder`` and, unless its finished file is there, ``*.mcap.partial``."""
    finished = {p for p in Path(folder).rglob("*.mcap") if not p.is_dir()}
    partial = {
        p
        for p in Path(folder).rglob("*.mcap.partial")
        if not p.is_dir()
        and (every_partial or not {_finished(p), p.with_name(p.name[:-8])} & finished)
    }
    return sorted(finished | partial)


def read_records(
    path: str | Path | Iterable[str | Path],
    *,
    run: int | None = None,
    episode: int | None = None,
    pictures: bool = True,
) -> Records:
    """A record file, a folder of them or a list of files; ``run`` (``episode``): only that, and
    with an intact summary only its chunks read."""
    one = isinstance(path, (str, Path))
    paths = [Path(p) for p in ([path] if one else path)]
    folder = paths[0] if one and paths[0].is_dir() else None
    if folder is not None:  # unreadable files and .partial ones beside their finished file: warned
        paths = find_record_files(folder)
        if not paths:
            raise RecordsNotFound(f"{folder}: no .mcap record files under this folder")
        for q in sorted(set(find_record_files(folder, every_partial=True)) - set(paths)):
            why = f"an unfinished recording whose finished file {_finished(q)} is there (read it by name)"
            warnings.warn(f"{q}: not read: {why}", RecordsWarning, stacklevel=2)
    elif one and not paths[0].exists():
        raise RecordsNotFound(f"{paths[0]}: no such record file")
    window = None
    if run is not None:
        start = S.log_time_ns(run, episode or 0)
        stop = S.log_time_ns(run + 1, 0) if episode is None else S.log_time_ns(run, episode + 1)
        window = (start, stop)
    parts, bad = [], []
    for p in dict.fromkeys(paths):
        try:
            parts.append(_read_file(p, window, pictures))
        except RecordsError as e:
            if folder is None:
                raise
            bad.append(str(e))
            warnings.warn(f"not read: {e}", RecordsWarning, stacklevel=2)
    if not parts:
        raise RecordsError(f"{folder}: no readable record file: " + "; ".join(bad))
    frames, files = {}, [str(p["meta"].path) for p in parts]
    for key in _FRAMES:  # file after file; a column some files lack (fewer scores) is NaN
        cols, sizes = [p[key] for p in parts], [len(p[key]["run"]) for p in parts]
        names = dict.fromkeys(name for c in cols for name in c)
        whole = {
            n: np.concatenate([c[n] if n in c else np.full(k, np.nan) for c, k in zip(cols, sizes)])
            for n in names
        }
        frames[key] = pd.DataFrame(whole, copy=False)  # new arrays: each its own block, no copy
        codes = np.repeat(np.arange(len(parts), dtype=np.int32), sizes)
        frames[key].insert(0, "file", pd.Categorical.from_codes(codes, categories=files))
    q_values = {k: v for p in parts for k, v in p["q_values"].items()}
    return Records(**frames, files={f: p["meta"] for f, p in zip(files, parts)}, q_values=q_values)


def _read_file(path: Path, window, pictures: bool) -> dict[str, Any]:
    # a batch is stamped at its first episode: read from the run's start, then filter rows
    sc = scan(
        path, time_range=None if window is None else (window[0] - window[0] % S.RUN_NS, window[1])
    )
    meta = _meta(sc, pictures)
    dec = _decode(sc)
    for key in _FRAMES:  # the rows in the window, sorted by (run, episode, step)
        cols = dec[key]
        t = cols["run"].astype(np.int64) * S.RUN_NS + cols["episode"] * np.int64(S.EPISODE_NS)
        keep = None if window is None else (t >= window[0]) & (t < window[1])
        if keep is not None and not keep.all():
            cols, t = {k: v[keep] for k, v in cols.items()}, t[keep]
        t = t + cols["step"].astype(np.int64) * S.STEP_NS if "step" in cols else t
        order = np.argsort(t, kind="stable") if (np.diff(t) < 0).any() else None
        dec[key] = cols if order is None else {k: v[order] for k, v in cols.items()}
    _account(sc, meta, dec, window)
    return dec | {"meta": meta}


def _account(sc: Scan, meta: FileMeta, dec: dict, window) -> None:
    """Fill in what the file should hold, what it lost, its status; warn once if anything is wrong."""
    eps, closed = dec["episodes"], meta.closed or {}
    runs, per_run = expected_shape(meta.config, meta.obstacles, meta.closed)
    truncated = any(d.kind == "truncated" for d in sc.damage)
    stopped = any(d.kind == "stopped" for d in sc.damage)  # what was not read after it: lost
    finished = stopped or not truncated and not meta.partial and closed.get("complete") == "true"
    spans = [d.span for d in sc.damage if d.span is not None]
    shape = {"runs": runs, "per_run": per_run, "finished": finished, "window": window}
    expected, lost, absent = account(eps["run"], eps["episode"], spans=spans, **shape)
    problems = [d.what for d in sc.damage] + sc.notes
    if sc.dropped:
        problems.append(f"{sc.dropped} messages of channels defined in lost parts were dropped")
    if (lost or absent) and not sc.damage:
        problems.insert(0, _UNFINISHED[meta.partial, meta.closed is None])
    chunks = any(d.kind == "chunk" for d in sc.damage)
    heads = [f"lost {describe(lost, per_run)}"] if lost else ["no episode lost"] * chunks
    heads += [f"missing {describe(absent, per_run)} (not recorded)"] if absent else []
    held = sum(c.topic.startswith(PICTURE_PREFIXES) for c in sc.channels.values())
    if held and not (meta.pictures or meta.support_pictures) and (sc.damage and window is None):
        heads.append(f"lost the {held} pictures")
    problems += heads
    if not problems and (meta.partial or closed.get("complete") != "true"):
        problems.append(_UNFINISHED[meta.partial, meta.closed is None])
    meta.expected_runs, meta.expected_episodes, meta.problems = runs, expected, problems
    meta.lost = "; ".join(heads)
    meta.readable = bool(sc.metadata or sc.messages)
    meta.damaged = any(d.kind != "truncated" for d in sc.damage)
    meta.complete = not problems
    of = "" if expected is None else f" of {expected}"
    if len(eps["run"]):  # sorted: the last row is the last episode
        last = f"run {eps['run'][-1]} episode {eps['episode'][-1]}"
        n_subs = len(dec["substitutions"]["run"])
        kept = f"kept {len(eps['run'])}{of} episodes (up to {last}) and {n_subs} substitutions"
    else:
        kept = "no complete episode could be read" + (f" ({expected} expected)" if of else "")
        kept += "" if meta.readable else ", nor any other record"
    if problems:
        warnings.warn(f"{sc.path}: {'; '.join(problems)}; {kept}", RecordsWarning, stacklevel=4)
    elif not len(eps["run"]) and window is None:
        warnings.warn(f"{sc.path}: the file holds no episode records", RecordsWarning, stacklevel=4)


def _maze(mz: dict[str, str]) -> dict[str, Any]:
    out = {
        "layout": mz["layout"].split("\n"),
        "width": int(mz["width"]),
        "height": int(mz["height"]),
    }
    out["categories"] = json.loads(mz["categories"]) if "categories" in mz else None
    out["actions"] = mz["actions"].split(",") if "actions" in mz else None
    out["moves"] = [tuple(m) for m in json.loads(mz["moves"])] if "moves" in mz else None
    return out | (json.loads(mz["extra"]) if "extra" in mz else {})


_METADATA = {  # metadata record -> the FileMeta fields it gives
    "config": lambda rec: {
        "config": json.loads(rec["json"]) if "json" in rec else None,
        "config_yaml": rec.get("yaml"),
    },
    "seeds": lambda rec: {"seeds": json.loads(rec["json"])},
    "versions": lambda rec: {"versions": dict(rec)},
    "maze": lambda rec: {"maze": _maze(rec)},
    "obstacles": lambda rec: {"obstacles": {int(k): v for k, v in json.loads(rec["json"]).items()}},
    "info": lambda rec: {"info": {k: json.loads(v) for k, v in rec.items()}},
    "closed": lambda rec: {"closed": dict(rec)},
    "recording": lambda rec: {"record": rec.get("record", "steps")},
}


def _meta(sc: Scan, pictures: bool) -> FileMeta:
    """The file's metadata records and pictures; one that does not parse is damage, not an error."""
    meta = FileMeta(path=sc.path, partial=sc.path.name.endswith(".partial"))
    for name, parse in _METADATA.items():
        try:
            vars(meta).update(parse(sc.metadata[name]) if name in sc.metadata else {})
        except Exception as e:
            sc.add("metadata", f"metadata record '{name}' does not parse ({type(e).__name__})")
    for topic, msgs in sc.messages.items() if pictures and sc.messages else ():
        *_, a, b = topic.split("/")
        try:
            if topic.startswith(PICTURE_PREFIXES[0]):
                meta.pictures[int(b)] = S.CompressedImage.FromString(msgs[-1][1]).data
            elif topic.startswith(PICTURE_PREFIXES[1]):
                meta.support_pictures[int(a), int(b)] = S.CompressedImage.FromString(
                    msgs[-1][1]
                ).data
        except Exception as e:
            sc.add("decode", f"the picture message on {topic} does not decode ({type(e).__name__})")
    return meta


PICTURE_PREFIXES = (S.TOPIC_PICTURES + "/", S.TOPIC_SUPPORT + "/")


def _decode(sc: Scan) -> dict[str, Any]:
    """The episode batches of a file of ours of this format (else RecordsError); a message that
    passed its chunk's CRC but does not decode is damage."""
    episodes = [ch for ch in sc.channels.values() if ch.topic == S.TOPIC_EPISODES]
    ours = (
        (sc.library or "").startswith("pipeline.records/") or "recording" in sc.metadata or episodes
    )
    if (sc.metadata or sc.messages) and not ours:
        topics = sorted({ch.topic for ch in sc.channels.values()})
        held = f" (channels {', '.join(topics[:4])}{', ...' * (len(topics) > 4)})" * bool(topics)
        by = f"by {sc.library!r}" if sc.library else "by another program"
        raise RecordsError(
            f"{sc.path}: not a record file of this pipeline: an MCAP file written {by}{held}, "
            f"without the 'recording' metadata or an {S.TOPIC_EPISODES} channel"
        )
    try:  # the schema record of the episodes channel (lost: this writer's)
        ids = [c.schema_id for c in episodes if c.schema_id in sc.schemas]
        check_schema(sc.schemas[ids[0]].data if ids else None, sc.library)
    except FormatError as e:
        raise RecordsError(f"{sc.path}: {e}") from None
    msgs = sc.messages.get(S.TOPIC_EPISODES, [])
    try:
        return decode_batches([d for _, d in msgs], str(sc.path))
    except Exception:  # keep the messages that decode
        good = []
    for t, data in msgs:
        try:
            decode_batches([data], str(sc.path))
            good.append(data)
        except Exception as e:
            run, ep, _ = S.split_log_time(t)
            what = f"the episode batch stamped run {run} episode {ep} does not decode ({type(e).__name__}: {e})"
            sc.add("decode", what, (t, t))
    return decode_batches(good, str(sc.path))
