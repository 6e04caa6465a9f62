"""Vectorised decoding of many ``fsrl.records.EpisodeBatch`` messages at once.

The Protobuf runtime turns every packed element into a Python int (about 1 us each, so seconds
for a paper-scale file). Here a small wire-level walk over each message's fields (a few dozen tag
reads a batch) notes where each packed array lies in one joined buffer; then every column of every
message is decoded in a handful of numpy operations: gather the bytes, find the varint ends (bytes
< 0x80), and OR the 7-bit groups. :func:`decode_batches` returns None for a message of unexpected
shape (unknown wire type, unpacked repeated field) and :func:`decode_batches_protobuf`, the
Protobuf runtime, decodes instead: this is an accelerator, never a second truth. Both return the
same flat columns (tests compare them); :func:`pipeline.records.reader` builds the frames.
"""
from __future__ import annotations

import struct

import numpy as np

from . import schema as S

# sub-message field number -> (column, kind); kind "v" varint, "f" float32, "d" float64
_TOP = {2: ("episode", "v"), 8: ("q_values", "f")}
_SUMMARY = {1: ("s_steps", "v"), 2: ("s_collisions", "v"), 3: ("s_return", "d"), 4: ("s_reached_goal", "v"),
            5: ("s_prevented", "v"), 6: ("s_epsilon", "d"), 7: ("s_greedy_optimal", "v")}
_STEPS = {1: ("states", "v"), 2: ("actions", "v"), 3: ("rewards", "f"), 4: ("flags", "v")}
_REC = {1: ("r_episode", "v"), 2: ("r_step", "v"), 3: ("r_state", "v"), 4: ("r_action", "v"),
        5: ("r_picture", "v"), 6: ("r_predicted", "v"), 7: ("r_true", "v"), 9: ("scores", "f")}
_UNSAFE = {1: ("u_episode", "v"), 2: ("u_step", "v"), 3: ("u_state", "v"), 4: ("u_action", "v"),
           5: ("u_source", "v")}
_SUBS = {3: _SUMMARY, 4: _STEPS, 5: _REC, 6: _UNSAFE}
COLUMNS = {name: kind for table in (_TOP, *_SUBS.values()) for name, kind in table.values()}

# column -> (sub-message attribute or "", field attribute): the same columns through the runtime
_RUNTIME: dict[str, tuple[str, str]] = {}
for _sub, _cls, _table in (("", S.EpisodeBatch, _TOP), ("summary", S.EpisodeSummaries, _SUMMARY),
                           ("steps", S.Steps, _STEPS), ("recognitions", S.Recognitions, _REC),
                           ("unsafe_added", S.UnsafeAdditions, _UNSAFE)):
    for _f, (_name, _) in _table.items():
        _RUNTIME[_name] = (_sub, _cls.DESCRIPTOR.fields_by_number[_f].name)
_DTYPE = {"v": np.int64, "f": np.float32, "d": np.float64}


class _Unexpected(Exception):
    pass


def _varint(buf: bytes, pos: int) -> tuple[int, int]:
    b = buf[pos]
    if b < 0x80:
        return b, pos + 1
    result, shift = 0, 0
    while True:
        b = buf[pos]
        result |= (b & 0x7F) << shift
        pos += 1
        if b < 0x80:
            return result, pos
        shift += 7
        if shift > 63:
            raise _Unexpected("varint too long")


def _walk(buf: bytes, pos: int, end: int, table: dict, spans: dict, scalars: dict, i: int,
          subs: dict | None = None) -> None:
    """Note the (start, end, message) spans of the packed fields of one (sub)message in ``spans``
    and its varint scalars (field number -> value) in ``scalars``."""
    while pos < end:
        tag, pos = _varint(buf, pos)
        field, wt = tag >> 3, tag & 7
        if wt == 2:
            ln, pos = _varint(buf, pos)
            if field in table:
                spans[table[field][0]].append((pos, pos + ln, i))
            elif subs is not None and field in subs:
                _walk(buf, pos, pos + ln, subs[field], spans, scalars.setdefault(field, {}), i)
            pos += ln
        elif wt == 0:
            if field in table:
                raise _Unexpected("unpacked repeated field")
            scalars[field], pos = _varint(buf, pos)
        elif wt == 1:
            pos += 8
        elif wt == 5:
            pos += 4
        else:
            raise _Unexpected(f"wire type {wt}")
    if pos != end:
        raise _Unexpected("field runs past its message")


def _gather(arr: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """Concatenate ``arr[s:e]`` for the (s, e) rows of ``spans``."""
    if len(spans) == 0:
        return arr[:0]
    lengths = spans[:, 1] - spans[:, 0]
    total = int(lengths.sum())
    if total == 0:
        return arr[:0]
    offsets = np.cumsum(lengths) - lengths
    idx = np.arange(total, dtype=np.int64) + np.repeat(spans[:, 0] - offsets, lengths)
    return arr[idx]


def _decode_varints(raw: np.ndarray, spans: np.ndarray, n_msgs: int, owner: np.ndarray):
    """Values (int64) of the packed varints in ``spans`` and how many each message holds."""
    data = _gather(raw, spans)
    if data.size == 0:
        return np.zeros(0, np.int64), np.zeros(n_msgs, np.int64)
    term = data < 0x80
    if term.all():
        values = data.astype(np.int64)
    else:
        if not term[-1]:
            raise _Unexpected("truncated varint")
        ends = np.flatnonzero(term)
        starts = np.concatenate(([0], ends[:-1] + 1))
        value_id = np.repeat(np.arange(len(ends)), ends - starts + 1)
        shift = (np.arange(len(data)) - starts[value_id]).astype(np.uint64) * np.uint64(7)
        if int(shift.max()) > 63:
            raise _Unexpected("varint too long")
        groups = (data & 0x7F).astype(np.uint64) << shift
        values = np.bitwise_or.reduceat(groups, starts).view(np.int64)
    lengths = spans[:, 1] - spans[:, 0]
    cum = np.concatenate(([0], np.cumsum(term)))
    bounds = np.concatenate(([0], np.cumsum(lengths)))
    per_span = cum[bounds[1:]] - cum[bounds[:-1]]
    counts = np.bincount(owner, weights=per_span, minlength=n_msgs).astype(np.int64)
    return values, counts


def _decode_fixed(raw: np.ndarray, spans: np.ndarray, n_msgs: int, owner: np.ndarray, dtype: str):
    size = np.dtype(dtype).itemsize
    data = _gather(raw, spans)
    if data.size % size or (len(spans) and ((spans[:, 1] - spans[:, 0]) % size).any()):
        raise _Unexpected("packed fixed-size field length")
    lengths = (spans[:, 1] - spans[:, 0]) // size if len(spans) else np.zeros(0, np.int64)
    counts = np.bincount(owner, weights=lengths, minlength=n_msgs).astype(np.int64)
    return data.view(dtype).astype(_DTYPE["f" if size == 4 else "d"]), counts


def decode_batches(messages: list[bytes]) -> dict | None:
    """Flat columns of EpisodeBatch messages, or None if a message has an unexpected shape.

    Returns ``run``, ``n_actions``, ``n_categories`` (one per message), every column of
    :data:`COLUMNS` (all messages concatenated) and ``counts`` (column -> per-message counts)."""
    n = len(messages)
    buf = b"".join(messages)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum([len(m) for m in messages], out=offsets[1:])
    spans: dict[str, list] = {k: [] for k in COLUMNS}
    run, n_act, n_cat = np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64)
    try:
        for i in range(n):
            scal: dict = {}
            _walk(buf, int(offsets[i]), int(offsets[i + 1]), _TOP, spans, scal, i, _SUBS)
            run[i], n_act[i] = scal.get(1, 0), scal.get(7, 0)
            n_cat[i] = scal.get(5, {}).get(8, 0)
        raw = np.frombuffer(buf, dtype=np.uint8)
        out: dict = {"run": run, "n_actions": n_act, "n_categories": n_cat, "counts": {}}
        for k, kind in COLUMNS.items():
            sp = np.array(spans[k], dtype=np.int64).reshape(-1, 3)
            if kind == "v":
                out[k], out["counts"][k] = _decode_varints(raw, sp[:, :2], n, sp[:, 2])
            else:
                out[k], out["counts"][k] = _decode_fixed(raw, sp[:, :2], n, sp[:, 2], "<f4" if kind == "f" else "<f8")
    except (_Unexpected, IndexError, struct.error):
        return None
    return out


def decode_batches_protobuf(messages: list[bytes]) -> dict:
    """The same flat columns as :func:`decode_batches`, through the Protobuf runtime (slow)."""
    msgs = [S.EpisodeBatch.FromString(m) for m in messages]
    out: dict = {"run": np.array([m.run for m in msgs], np.int64),
                 "n_actions": np.array([m.n_actions for m in msgs], np.int64),
                 "n_categories": np.array([m.recognitions.n_categories for m in msgs], np.int64), "counts": {}}
    for k, kind in COLUMNS.items():
        sub, attr = _RUNTIME[k]
        lists = [list(getattr(getattr(m, sub) if sub else m, attr)) for m in msgs]
        out["counts"][k] = np.array([len(x) for x in lists], np.int64)
        out[k] = np.array([v for x in lists for v in x], dtype=_DTYPE[kind])
    return out
