"""Episode batches (``pipeline/rl/sink.py``) to ``fsrl.records.EpisodeBatch`` bytes and back, every
column named by the one table :data:`.schema.MESSAGES` (docs/records.md "The schema").

Both ways go through the raw views (``schema.message_classes(view=True)``: every packed column
declared ``bytes``, the same wire bytes): a column is set as ``array.tobytes()`` and read with
``np.frombuffer``, no Python object per element and no hand-written wire code; the views decode an
order of magnitude faster than the real classes (``python -m benchmarks.records_overhead``). A code
column with a value of 128 or more (varints of several bytes) goes through the real classes, that
column alone; a message the views do not read exactly (an unknown field, a column split in two) is
re-serialized by the real classes first. Same bytes and columns as the runtime (tested).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2

from . import schema as S
from .schema import CODE, F32, F64, FLAG_BITS, I32, MESSAGES, SMALL, U32, Field

SUBS = {f.name: f.type for f in MESSAGES["EpisodeBatch"] if isinstance(f.type, str)}
COLUMNS = {
    m: [f for f in fs if f.repeated and not isinstance(f.type, str)] for m, fs in MESSAGES.items()
}
REWARDS, SMALL_REWARDS = (f for f in COLUMNS["Steps"] if f.column == "reward")  # one per batch
TRANSITIONS = COLUMNS["Steps"][0]  # two values a step: S.TRANSITION_PARTS
FIXED = {F32: "<f4", F64: "<f8", U32: "<u4", I32: "<i4"}  # fixed-width fields; others varints
OUR_SCHEMA = S.file_descriptor_set(S.EpisodeBatch)
VIEWS = S.message_classes(view=True)


def _payload(msg: str, f: Field, a: np.ndarray) -> bytes:
    """A checked column's payload: a code column of uint8 (every value below 128, its own
    varint byte: :mod:`.batch_check`) as it is, of another dtype through the runtime."""
    if f.type == CODE and a.dtype == np.uint8:
        return a.tobytes()
    if f.type == CODE:  # varints of several bytes: the runtime
        whole = S.CLASSES[msg](**{f.name: a.tolist()}).SerializeToString()
        return getattr(VIEWS[msg].FromString(whole), f.name)
    if f.type == SMALL:  # sint32 zigzag of values in -64..63, one byte each: 0,-1,1 -> 0,1,2
        small = a.astype(np.int8, copy=False)
        return ((small << 1) ^ (small >> 7)).view(np.uint8).tobytes()
    return a.tobytes()


def _message(msg: str, b: Mapping[str, Any]):
    cols = b["cols"].get(msg, {})
    kw = {f.name: _payload(msg, f, cols[f.name]) for f in COLUMNS[msg] if len(cols.get(f.name, ()))}
    kw.update({k: v for k, v in b["scalars"].get(msg, {}).items() if v})
    for field, sub in SUBS.items() if msg == "EpisodeBatch" else ():
        if (v := _message(sub, b)) is not None:
            kw[field] = v
    return VIEWS[msg](**kw) if kw else None


def encode_batch(b: Mapping[str, Any]) -> bytes:
    """The ``EpisodeBatch`` bytes of a checked batch (:func:`.batch_check.check_batch`): the bytes
    the real class filled through the runtime serializes (tested)."""
    return _message("EpisodeBatch", b).SerializeToString(deterministic=True)


class FormatError(ValueError):
    """A file's episode batches use a schema this reader cannot decode."""


def check_schema(schema_data: bytes | None, library: str | None) -> None:
    """Refuse (:class:`FormatError`) episode batches of another schema record than this format's
    (``None``: lost, this writer's assumed); ``library``: the file header's, which names the format."""
    if schema_data in (None, OUR_SCHEMA):
        return
    try:
        if S.FILE_DESCRIPTOR_PROTO in descriptor_pb2.FileDescriptorSet.FromString(schema_data).file:
            return
    except Exception:  # not a FileDescriptorSet: not ours either
        pass
    ours = (library or "").startswith("pipeline.records/")
    written = f"record format {library.rsplit('/', 1)[1]}" if ours else "another record schema"
    raise FormatError(
        f"its episode batches use {written}; this reader reads format {S.FORMAT_VERSION}: re-run "
        "the trials that wrote it (or read it with the commit of the pipeline that wrote it)"
    )


def _values(raw: list[bytes], f: Field, column) -> tuple[np.ndarray, np.ndarray]:
    """A column's values over messages (``raw``: its payload in each) and how many each holds;
    ``column(payload)``: the values of a payload through the runtime (multi-byte varints)."""
    lens, b = np.fromiter(map(len, raw), np.int64, len(raw)), b"".join(raw)
    if f.type in FIXED:
        size = np.dtype(FIXED[f.type]).itemsize
        if (lens % size).any():
            raise ValueError("a fixed-width column is not whole elements")
        return np.frombuffer(b, FIXED[f.type]), lens // size
    values = np.frombuffer(b, np.uint8)
    if (values >= 128).any():  # the runtime reads them, faster than numpy
        if (values[np.cumsum(lens)[lens > 0] - 1] >= 128).any():
            raise ValueError("a varint column does not end with a whole value")
        ends = np.r_[0, np.cumsum(values < 128)][np.r_[0, np.cumsum(lens)]]
        return np.array(column(b)), np.diff(ends)
    if f.type == SMALL:  # zigzag back: 0, 1, 2, 3 -> 0, -1, 1, -2
        return (values >> 1).astype(np.int8) ^ -(values & 1).astype(np.int8), lens
    return values, lens


def _flat(data: list[bytes]) -> dict:
    """Every column of the messages, concatenated, and its length in each, through the raw views."""
    top = []
    for d in data:
        v = VIEWS["EpisodeBatch"].FromString(d)
        v.DiscardUnknownFields()
        if v.ByteSize() != len(d):  # not canonical: re-serialized by the real classes
            m = S.EpisodeBatch.FromString(d)
            m.DiscardUnknownFields()
            v = VIEWS["EpisodeBatch"].FromString(m.SerializeToString(deterministic=True))
        top.append(v)
    msgs = {"EpisodeBatch": top} | {sub: [getattr(v, f) for v in top] for f, sub in SUBS.items()}
    out: dict = {
        "run": np.array([m.run for m in top], np.int64),
        "n_actions": np.array([m.n_actions for m in top]),
        "n_categories": np.array([m.recognitions.n_categories for m in top], np.int64),
    }
    for msg, fields in COLUMNS.items():
        for f in fields:

            def column(payload, msg=msg, name=f.name):
                whole = VIEWS[msg](**{name: payload}).SerializeToString()
                return getattr(S.CLASSES[msg].FromString(whole), name)

            out[msg, f.name] = _values([getattr(m, f.name) for m in msgs[msg]], f, column)
    values, n = out["Steps", TRANSITIONS.name]
    if (n % 2).any():
        raise ValueError(f"Steps.{TRANSITIONS.name} does not hold whole pairs")
    out["Steps", TRANSITIONS.name] = values.reshape(-1, 2), n // 2  # one pair a step
    return out


def decode_batches(data: list[bytes], name: str) -> dict:
    """The frames' columns (``steps``, ``recognitions``, ``unsafe``, ``substitutions``,
    ``episodes``) and ``q_values`` ((name, run, episode) -> table) of ``EpisodeBatch`` messages.
    Raises ValueError naming the problem when the messages' arrays do not fit together."""
    return _columns(_flat(data), name)


def _frame(flat: dict, msg: str, head: dict) -> dict:
    """The frame columns of ``msg``'s fields in field order."""
    out = dict(head)
    for f in COLUMNS[msg]:
        if f.name != "scores":
            v = flat[msg, f.name][0]
            out[f.column] = v != 0 if f.dtype == "bool" else v.astype(f.dtype)
    return out


def _transitions(pair: np.ndarray, reward: np.ndarray) -> dict[str, np.ndarray]:
    """The steps frame's ``state``, ``action``, ``reward`` and ``flags`` from the
    ``Steps.transitions`` pairs (rows: state, action * 32 + flags)."""
    code = pair[:, 1]
    parts = (pair[:, 0], code >> FLAG_BITS, code & (2**FLAG_BITS - 1))
    state, action, flags = (
        v.astype(dtype) for v, (_, _, dtype) in zip(parts, S.TRANSITION_PARTS, strict=True)
    )
    return {"state": state, "action": action, "reward": reward, "flags": flags}


def _columns(flat: dict, name: str) -> dict[str, Any]:
    def bad(why: str):
        return ValueError(f"{name}: episode batch messages are inconsistent: {why}")

    count = {k: v[1] for k, v in flat.items() if isinstance(k, tuple)}
    n_eps = count["EpisodeBatch", "episode"]
    lens = flat["EpisodeSummaries", "steps"][0].astype(np.int64)
    if not count["Steps", TRANSITIONS.name].any():  # recorded without steps (record=episodes)
        lens = np.zeros_like(lens)
    n_float, n_small = count["Steps", REWARDS.name], count["Steps", SMALL_REWARDS.name]
    if ((n_float > 0) & (n_small > 0)).any():
        raise bad("a batch has rewards in both reward columns")
    count["Steps", REWARDS.name] = n_float + n_small
    per_msg = np.repeat(np.arange(len(n_eps)), n_eps)
    rows = {"EpisodeSummaries": n_eps, "Steps": np.bincount(per_msg, lens, len(n_eps))}
    rows |= {m: count[m, "episode"] for m in ("Recognitions", "UnsafeAdditions", "Substitutions")}
    for msg, expected in rows.items():
        for f in (f for f in COLUMNS[msg] if f.name not in ("scores", SMALL_REWARDS.name)):
            if not np.array_equal(count[msg, f.name], expected):
                raise bad(f"{msg}.{f.name} does not have one entry per row")
    rec_m, n_sc, ncat = (
        count["Recognitions", "episode"],
        count["Recognitions", "scores"],
        flat["n_categories"],
    )
    if not np.array_equal(n_sc, np.where(n_sc > 0, rec_m * ncat, 0)):
        raise bad("scores do not have n_categories columns")
    ep_run = np.repeat(flat["run"], n_eps).astype(np.int32)
    ep_ep = flat["EpisodeBatch", "episode"][0].astype(np.int32)
    starts = np.repeat(np.cumsum(lens) - lens, lens)
    small = np.repeat(n_small > 0, n_float + n_small)  # the steps whose rewards are small_rewards
    reward = np.empty(len(small), np.float32)
    reward[small] = flat["Steps", SMALL_REWARDS.name][0]
    reward[~small] = flat["Steps", REWARDS.name][0]
    step = (np.arange(len(starts)) - starts).astype(np.int32)
    head = {"run": np.repeat(ep_run, lens), "episode": np.repeat(ep_ep, lens), "step": step}
    steps = head | _transitions(flat["Steps", TRANSITIONS.name][0], reward)
    steps |= {flag: (steps["flags"] & bit) != 0 for flag, bit in S.FLAG_NAMES.items()}

    rec, unsafe, subs = (
        _frame(flat, m, {"run": np.repeat(flat["run"], count[m, "episode"]).astype(np.int32)})
        for m in ("Recognitions", "UnsafeAdditions", "Substitutions")
    )
    rec["correct"] = rec["predicted"] == rec["true"]
    has, width = n_sc > 0, int(ncat[n_sc > 0].max()) if n_sc.any() else 0
    if width:
        values = flat["Recognitions", "scores"][0].astype(np.float32)
        if has[rec_m > 0].all() and (ncat[has] == width).all():
            scores = values.reshape(-1, width)
        else:  # some batches without scores (or fewer columns): NaN there
            scores = np.full((len(rec["run"]), width), np.nan, np.float32)
            row, pos = np.cumsum(rec_m) - rec_m, np.cumsum(n_sc) - n_sc
            for r, p, m, k in zip(row[has], pos[has], rec_m[has], ncat[has]):
                scores[r : r + m, :k] = values[p : p + m * k].reshape(m, k)
        rec |= {f"score_{j}": scores[:, j] for j in range(width)}
    ep_key = ep_run.astype(np.int64) << 32 | ep_ep
    order = np.argsort(ep_key, kind="stable")
    per_episode = {}
    for what, cols in (("recognitions", rec), ("unsafe", unsafe), ("substitutions", subs)):
        key = cols["run"].astype(np.int64) << 32 | cols["episode"]
        pos = np.searchsorted(ep_key[order], key)
        if len(key) and (pos.max() >= len(order) or not np.array_equal(ep_key[order][pos], key)):
            raise bad(f"{what} of episodes that are not in their batch")
        per_episode[what] = np.bincount(order[pos], minlength=len(ep_key)).astype(np.int32)
    episodes = _frame(flat, "EpisodeSummaries", {"run": ep_run, "episode": ep_ep})
    episodes["n_recognitions"], episodes["n_unsafe_added"] = (
        per_episode["recognitions"],
        per_episode["unsafe"],
    )
    q_values, (q, n_q), row = {}, flat["EpisodeBatch", "q_values"], np.cumsum(n_eps) - n_eps
    pos = np.cumsum(n_q) - n_q
    for i in np.flatnonzero(n_q):
        e, na = int(n_eps[i]), int(flat["n_actions"][i])
        if not na or n_q[i] % (na * e):
            raise bad("q_values do not have n_actions columns for every episode")
        tables = q[pos[i] : pos[i] + n_q[i]].astype(np.float32).reshape(e, -1, na)
        for j in range(e):
            q_values[name, int(ep_run[row[i] + j]), int(ep_ep[row[i] + j])] = tables[j]
    frames = {"steps": steps, "recognitions": rec, "unsafe": unsafe, "substitutions": subs}
    return frames | {"episodes": episodes, "q_values": q_values}
