"""Load MCAP records into pandas DataFrames (docs/records.md): ``read_records("datasets/runs/fig8").episodes``.

A damaged or truncated file keeps what its intact parts hold (:mod:`.scan`), with a :class:`RecordsWarning` naming the
file and what was lost (:mod:`.loss`); a file with nothing to read raises :class:`RecordsError`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from . import schema as S
from .codec import FormatError, check_schema, decode_batches
from .file_meta import FileMeta, file_meta, message_counts
from .loss import DAMAGE_KINDS, account, expected_shape
from .scan import Damage, RecordsError, Scan, scan

_FRAMES = ("steps", "episodes", "recognitions", "unsafe", "substitutions")
#: The first sentence of the warning about an undamaged file that is not complete, by (partial, unclosed).
_UNFINISHED = {
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


def _finished(
    p: Path,
) -> Path:  # what a .partial becomes: beside it or, in a .staging-<pid> folder, outside that
    final = p.with_name(p.name[: -len(".partial")])
    staging = [i for i, part in enumerate(final.parts) if part.startswith(".staging-")]
    return Path(*final.parts[: staging[-1]], *final.parts[staging[-1] + 1 :]) if staging else final


def find_record_files(folder: str | Path, *, every_partial: bool = False) -> list[Path]:
    """Every ``*.mcap`` under ``folder`` and, unless its finished file is there too, ``*.mcap.partial``, sorted."""
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
    """A record file, a folder of them or a list of files; ``run`` (``episode``): only that, only its chunks read."""
    one = isinstance(path, (str, Path))
    paths = [Path(p) for p in ([path] if one else path)]
    folder = paths[0] if one and paths[0].is_dir() else None
    if (
        folder is not None
    ):  # a file of a folder that cannot be read is left out with a warning; so is a .partial
        paths = find_record_files(folder)  # beside its finished file
        if not paths:
            raise RecordsNotFound(f"{folder}: no .mcap record files under this folder")
        for q in sorted(set(find_record_files(folder, every_partial=True)) - set(paths)):
            warnings.warn(
                f"{q}: not read: an unfinished recording whose finished file {_finished(q)} is there "
                "(read it by name)",
                RecordsWarning,
                stacklevel=2,
            )
    elif one and not paths[0].exists():
        raise RecordsNotFound(f"{paths[0]}: no such record file")
    window = None
    if run is not None:
        start = S.log_time_ns(run, episode or 0)
        window = (
            start,
            S.log_time_ns(run + 1, 0) if episode is None else S.log_time_ns(run, episode + 1),
        )
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
    for key in _FRAMES:  # one file after another; a column some files lack (fewer scores) is NaN
        cols, sizes = [p[key] for p in parts], [len(p[key]["run"]) for p in parts]
        # copy=False: the arrays are new, each becomes its own block (copying them into 2-D blocks is
        # a large share of reading a big file)
        frames[key] = pd.DataFrame(
            {
                name: np.concatenate(
                    [c[name] if name in c else np.full(n, np.nan) for c, n in zip(cols, sizes)]
                )
                for name in dict.fromkeys(name for c in cols for name in c)
            },
            copy=False,
        )
        codes = np.repeat(np.arange(len(parts), dtype=np.int32), sizes)
        frames[key].insert(0, "file", pd.Categorical.from_codes(codes, categories=files))
    return Records(
        **frames,
        files={f: p["meta"] for f, p in zip(files, parts)},
        q_values={k: v for p in parts for k, v in p["q_values"].items()},
    )


def _read_file(path: Path, window, pictures: bool) -> dict[str, Any]:
    # An EpisodeBatch is stamped at its first episode, so one stamped before the requested episodes of the run may
    # hold them: scan from the run's start, then filter rows.
    sc = scan(
        path, time_range=None if window is None else (window[0] - window[0] % S.RUN_NS, window[1])
    )
    dec, meta = _decode(sc), file_meta(sc, pictures)
    runs, per_run = expected_shape(meta.config, meta.obstacles, meta.closed)
    # the episodes of every batch read, when all are the same size bar each run's last: a lost batch holds as many
    sizes, ep = np.asarray(dec.get("batch_sizes", ()), dtype=np.int64), dec["episodes"]["episode"]
    full = (
        sizes[ep[np.cumsum(sizes) - 1] != per_run - 1] if per_run is not None and len(ep) else sizes
    )
    full = full if len(full) else sizes
    batch_size = int(full[0]) if sc.damage and len(full) and (full == full[0]).all() else None
    for key in _FRAMES:  # the rows in the window, sorted by (run, episode, step)
        cols = dec[key]
        t = (
            cols["run"].astype(np.int64) * S.RUN_NS
            + cols["episode"].astype(np.int64) * S.EPISODE_NS
        )
        keep = None if window is None else (t >= window[0]) & (t < window[1])
        if keep is not None and not keep.all():
            cols, t = {k: v[keep] for k, v in cols.items()}, t[keep]
        if "step" in cols:
            t = t + cols["step"].astype(np.int64) * S.STEP_NS
        order = np.argsort(t, kind="stable") if (np.diff(t) < 0).any() else None
        dec[key] = cols if order is None else {k: v[order] for k, v in cols.items()}
    eps, closed, n_subs = dec["episodes"], meta.closed or {}, len(dec["substitutions"]["run"])
    expected, problems, meta.lost = account(
        sc,
        eps["run"],
        eps["episode"],
        runs=runs,
        per_run=per_run,
        batch_size=batch_size,
        window=window,
        unfinished=any(d.kind == "truncated" for d in sc.damage)
        or closed.get("complete") != "true",
        counts=None if window is not None else message_counts(sc, closed, n_subs),
    )
    problems += sc.notes
    stats = sc.summary is not None and sc.summary.statistics is not None
    if (
        pictures
        and not (meta.pictures or meta.support_pictures or stats)
        and any(
            d.span is not None
            and d.span[0] == 0
            and d.kind in ("chunk", "bytes", "truncated")
            and not d.held
            for d in sc.damage
        )
    ):
        problems.append(
            "no picture could be read: the file's pictures, if it had any, were in the damaged part "
            "(they are stamped at time 0)"
        )
    if sc.dropped:
        problems.append(
            f"{sc.dropped} messages referred to channels defined in lost parts and were dropped"
        )
    if not sc.damage and (meta.partial or closed.get("complete") != "true"):
        problems.insert(0, _UNFINISHED[meta.partial, meta.closed is None])
    meta.expected_runs, meta.expected_episodes, meta.problems = runs, expected, problems
    meta.readable = bool(sc.metadata or sc.messages)
    meta.damaged = any(d.kind in DAMAGE_KINDS for d in sc.damage)
    meta.complete = sc.complete and not meta.partial and not problems
    of = "" if expected is None else f" of {expected}"
    if len(eps["run"]):  # sorted: the last row is the last episode
        kept = (
            f"kept {len(eps['run'])}{of} episodes (up to run {eps['run'][-1]} episode {eps['episode'][-1]}) "
            f"and {n_subs} substitutions"
        )
    else:  # with nothing readable, nothing is expected either
        kept = (
            "no complete episode could be read"
            + (f" ({expected} expected)" if of else "")
            + ("" if meta.readable else ", nor any other record")
        )
    if problems:
        warnings.warn(f"{path}: {'; '.join(problems)}; {kept}", RecordsWarning, stacklevel=3)
    elif not len(eps["run"]) and window is None:
        warnings.warn(f"{path}: the file holds no episode records", RecordsWarning, stacklevel=3)
    return dec | {"meta": meta}


def _decode(sc: Scan) -> dict[str, Any]:
    """The episode batches of a file of ours, of this format (else RecordsError); what does not decode is damage."""
    episodes = [ch for ch in sc.channels.values() if ch.topic == S.TOPIC_EPISODES]
    if (
        sc.metadata or sc.messages
    ):  # else our magic bytes and nothing after them that can be read: a cut copy
        if not (
            (sc.library or "").startswith("pipeline.records/")
            or "recording" in sc.metadata
            or episodes
        ):
            topics = sorted({ch.topic for ch in sc.channels.values()})
            held = (
                f" (channels {', '.join(topics[:4])}{', ...' if len(topics) > 4 else ''})"
                if topics
                else ""
            )
            raise RecordsError(
                f"{sc.path}: not a record file of this pipeline: an MCAP file written "
                f"{f'by {sc.library!r}' if sc.library else 'by another program'}{held}, "
                f"without the 'recording' metadata or an {S.TOPIC_EPISODES} channel"
            )
    try:  # the schema record of the episodes channel (lost: this writer's, scan.WRITER_CHANNELS)
        check_schema(
            next(
                (sc.schemas[c.schema_id].data for c in episodes if c.schema_id in sc.schemas), None
            ),
            sc.library,
        )
    except FormatError as e:
        raise RecordsError(f"{sc.path}: {e}") from None
    msgs = sc.messages.get(S.TOPIC_EPISODES, [])
    try:
        return decode_batches(msgs, str(sc.path))
    except Exception:  # a message that passed its chunk's CRC but does not parse: keep the rest
        good = []
    for t, data in msgs:
        try:
            decode_batches([(t, data)], str(sc.path))
        except Exception as e:
            run, ep, _ = S.split_log_time(t)
            sc.damage.append(
                Damage(
                    "decode",
                    f"the episode batch message stamped run {run} episode {ep} did not "
                    f"decode ({type(e).__name__}: {e})",
                    (t, t),
                )
            )
        else:
            good.append((t, data))
    return decode_batches(good, str(sc.path))
