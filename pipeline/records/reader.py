"""Load MCAP records into pandas DataFrames (DESIGN.md "Records").

    recs = read_records("datasets/runs/fig8")          # a file, or a folder of .mcap files
    recs.episodes.groupby("run").collisions.sum()
    recs.steps[recs.steps.collided]

A truncated or corrupt file (a killed run's ``.mcap.partial``, a cut copy) is read up to its last
complete chunk, with a :class:`RecordsWarning` that names the file and says what was lost; a file
from which nothing at all can be read still warns, it never silently returns nothing.
Decoding is vectorised: per message (one per episode) the packed arrays are appended to flat
lists, then each column is built with one numpy call.
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
from .decode import decode_episodes, decode_summaries
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


def _decode_episodes(messages: list[tuple[int, bytes]], name: str) -> dict[str, Any]:
    """Columns of the Episode messages: vectorised (:mod:`.decode`), or through the Protobuf
    runtime when a message has a shape the fast path does not handle."""
    fast = decode_episodes([d for _, d in messages])
    if fast is not None:
        out = _columns_from_fast(fast, name)
        if out is not None:
            return out
    return _decode_episodes_protobuf(messages, name)


def _columns_from_fast(d: dict[str, Any], name: str) -> dict[str, Any] | None:
    c = d["counts"]
    lens = c["states"]
    if not (np.array_equal(c["actions"], lens) and np.array_equal(c["flags"], lens)
            and np.array_equal(c["rewards"], lens)):
        return None
    rec_lens = c["r_step"]
    if any(not np.array_equal(c[k], rec_lens) for k in ("r_state", "r_action", "r_picture", "r_predicted", "r_true")):
        return None
    un_lens = c["u_step"]
    if any(not np.array_equal(c[k], un_lens) for k in ("u_state", "u_action", "u_source")):
        return None
    ncat = d["n_categories"]
    if not np.array_equal(c["scores"], np.where(c["scores"] > 0, rec_lens * ncat, 0)):
        return None
    ep_run_a, ep_ep_a = d["run"].astype(np.int32), d["episode"].astype(np.int32)
    flags_a = d["flags"].astype(np.uint8)
    steps = {"run": np.repeat(ep_run_a, lens), "episode": np.repeat(ep_ep_a, lens), "step": _step_index(lens),
             "state": d["states"].astype(np.int32), "action": d["actions"].astype(np.int8),
             "reward": d["rewards"].astype(np.float32), "flags": flags_a}
    for flag_name, bit in S.FLAG_NAMES.items():
        steps[flag_name] = (flags_a & bit) != 0
    rec = {"run": np.repeat(ep_run_a, rec_lens), "episode": np.repeat(ep_ep_a, rec_lens),
           "step": d["r_step"].astype(np.int32), "state": d["r_state"].astype(np.int32),
           "action": d["r_action"].astype(np.int8), "picture": d["r_picture"].astype(np.int16),
           "predicted": d["r_predicted"].astype(np.int8), "true": d["r_true"].astype(np.int8)}
    rec["correct"] = rec["predicted"] == rec["true"]
    n_rec = len(rec["step"])
    has_scores = c["scores"] > 0
    width = int(ncat[has_scores].max()) if has_scores.any() else 0
    if width:
        if has_scores[rec_lens > 0].all() and (ncat[has_scores] == width).all():
            scores = d["scores"].astype(np.float32).reshape(n_rec, width)
        else:
            scores = np.full((n_rec, width), np.nan, dtype=np.float32)
            row, pos = 0, 0
            for m, k, has in zip(rec_lens, ncat, has_scores):
                if has:
                    scores[row:row + m, :k] = d["scores"][pos:pos + m * k].reshape(m, k)
                    pos += m * k
                row += m
        for j in range(width):
            rec[f"score_{j}"] = scores[:, j]
    unsafe = {"run": np.repeat(ep_run_a, un_lens), "episode": np.repeat(ep_ep_a, un_lens),
              "step": d["u_step"].astype(np.int32), "state": d["u_state"].astype(np.int32),
              "action": d["u_action"].astype(np.int8), "source": d["u_source"].astype(np.int8)}
    sums, extras = decode_summaries(d["summaries"])
    episodes = {"run": ep_run_a, "episode": ep_ep_a, "steps": _i(sums["steps"], np.int32),
                "collisions": _i(sums["collisions"], np.int32), "return_": _i(sums["return_"], np.float64),
                "reached_goal": _i(sums["reached_goal"], bool), "prevented": _i(sums["prevented"], np.int32),
                "epsilon": _i(sums["epsilon"], np.float64), "n_recognitions": rec_lens.astype(np.int32),
                "n_unsafe_added": un_lens.astype(np.int32)}
    for k in sorted({k for e in extras for k in e}):
        episodes[k] = np.array([e.get(k, np.nan) for e in extras], dtype=np.float64)
    q_values = {}
    if c["q_values"].any():
        pos = 0
        for i, (cnt, na) in enumerate(zip(c["q_values"], d["n_actions"])):
            if cnt:
                if not na or cnt % na:
                    return None
                q_values[(name, int(d["run"][i]), int(d["episode"][i]))] = \
                    d["q_values"][pos:pos + cnt].astype(np.float32).reshape(-1, int(na))
                pos += cnt
    return {"steps": steps, "recognitions": rec, "unsafe": unsafe, "episodes": episodes, "q_values": q_values}


def _decode_episodes_protobuf(messages: list[tuple[int, bytes]], name: str) -> dict[str, Any]:
    ep_run, ep_ep, lens, rec_lens, un_lens = [], [], [], [], []
    states, actions, rewards, flags = [], [], [], []
    r_step, r_state, r_action, r_pic, r_pred, r_true, r_scores, r_ncat = [], [], [], [], [], [], [], []
    u_step, u_state, u_action, u_source = [], [], [], []
    sums = {k: [] for k in ("steps", "collisions", "return_", "reached_goal", "prevented", "epsilon")}
    extras: list[dict[str, float]] = []
    q_values: dict[tuple[str, int, int], np.ndarray] = {}
    from_string = S.Episode.FromString
    for _, data in messages:
        ep = from_string(data)
        st = ep.steps
        ep_run.append(ep.run)
        ep_ep.append(ep.episode)
        lens.append(len(st.states))
        states.extend(st.states)
        actions.extend(st.actions)
        rewards.extend(st.rewards)
        flags.extend(st.flags)
        rc = ep.recognitions
        m = len(rc.step)
        rec_lens.append(m)
        if m:
            r_step.extend(rc.step)
            r_state.extend(rc.state)
            r_action.extend(rc.action)
            r_pic.extend(rc.picture)
            r_pred.extend(rc.predicted)
            r_true.extend(rc.true_category)
            r_ncat.append(rc.n_categories)
            r_scores.append(np.array(rc.scores, dtype=np.float32))
        un = ep.unsafe_added
        k = len(un.step)
        un_lens.append(k)
        if k:
            u_step.extend(un.step)
            u_state.extend(un.state)
            u_action.extend(un.action)
            u_source.extend(un.source)
        sm = ep.summary
        for key, col in sums.items():
            col.append(getattr(sm, key))
        extras.append(dict(sm.extra) if len(sm.extra) else {})
        if ep.n_actions:
            q_values[(name, ep.run, ep.episode)] = np.array(ep.q_values, dtype=np.float32).reshape(-1, ep.n_actions)

    ep_run_a, ep_ep_a = _i(ep_run, np.int32), _i(ep_ep, np.int32)
    lens_a, rec_lens_a, un_lens_a = _i(lens, np.int64), _i(rec_lens, np.int64), _i(un_lens, np.int64)
    flags_a = _i(flags, np.uint8)
    steps = {"run": np.repeat(ep_run_a, lens_a), "episode": np.repeat(ep_ep_a, lens_a),
             "step": _step_index(lens_a), "state": _i(states, np.int32), "action": _i(actions, np.int8),
             "reward": _i(rewards, np.float32), "flags": flags_a}
    for flag_name, bit in S.FLAG_NAMES.items():
        steps[flag_name] = (flags_a & bit) != 0

    rec = {"run": np.repeat(ep_run_a, rec_lens_a), "episode": np.repeat(ep_ep_a, rec_lens_a),
           "step": _i(r_step, np.int32), "state": _i(r_state, np.int32), "action": _i(r_action, np.int8),
           "picture": _i(r_pic, np.int16), "predicted": _i(r_pred, np.int8), "true": _i(r_true, np.int8)}
    rec["correct"] = rec["predicted"] == rec["true"]
    n_rec = len(rec["step"])
    ncat = max(r_ncat, default=0)
    if ncat:
        if all(c == ncat for c in r_ncat):  # the usual case: one recogniser, scores everywhere
            scores = np.concatenate(r_scores).reshape(n_rec, ncat)
        else:  # some episodes without scores (or fewer columns): NaN there
            scores = np.full((n_rec, ncat), np.nan, dtype=np.float32)
            row = 0
            for m, c, sc in zip(rec_lens_a[rec_lens_a > 0], r_ncat, r_scores):
                if c:
                    scores[row:row + m, :c] = sc.reshape(m, c)
                row += m
        for j in range(ncat):
            rec[f"score_{j}"] = scores[:, j]

    unsafe = {"run": np.repeat(ep_run_a, un_lens_a), "episode": np.repeat(ep_ep_a, un_lens_a),
              "step": _i(u_step, np.int32), "state": _i(u_state, np.int32), "action": _i(u_action, np.int8),
              "source": _i(u_source, np.int8)}

    episodes = {"run": ep_run_a, "episode": ep_ep_a, "steps": _i(sums["steps"], np.int32),
                "collisions": _i(sums["collisions"], np.int32), "return_": _i(sums["return_"], np.float64),
                "reached_goal": _i(sums["reached_goal"], bool), "prevented": _i(sums["prevented"], np.int32),
                "epsilon": _i(sums["epsilon"], np.float64), "n_recognitions": rec_lens_a.astype(np.int32),
                "n_unsafe_added": un_lens_a.astype(np.int32)}
    extra_keys = sorted({k for e in extras for k in e})
    for k in extra_keys:
        episodes[k] = np.array([e.get(k, np.nan) for e in extras], dtype=np.float64)
    return {"steps": steps, "recognitions": rec, "unsafe": unsafe, "episodes": episodes, "q_values": q_values}


def _decode_substitutions(messages: list[tuple[int, bytes]]) -> dict[str, np.ndarray]:
    cols = {k: [] for k in ("run", "episode", "step", "picture", "category", "position")}
    for _, data in messages:
        m = S.Substitution.FromString(data)
        for k, col in cols.items():
            col.append(getattr(m, k))
    types = {"run": np.int32, "episode": np.int32, "step": np.int32, "picture": np.int16,
             "category": np.int8, "position": np.int8}
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


def _read_file(path: Path, time_range, pictures: bool) -> dict[str, Any]:
    sc = scan(path, time_range=time_range)
    name = str(path)
    ep_msgs = sc.messages.get(S.TOPIC_EPISODES, [])
    try:
        dec = _decode_episodes(ep_msgs, name)
    except Exception as e:  # a message that passed the chunk CRC but does not parse: keep the rest
        good = []
        for t, data in ep_msgs:
            try:
                S.Episode.FromString(data)
                good.append((t, data))
            except Exception:
                pass
        sc.problems.append(f"{len(ep_msgs) - len(good)} episode messages did not decode ({type(e).__name__})")
        dec = _decode_episodes(good, name)
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
