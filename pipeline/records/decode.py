"""Vectorised decoding of many ``fsrl.records.Episode`` messages at once.

The Protobuf runtime turns every packed element into a Python int (about 1 us each, so several
seconds for a paper-scale file). Here a small wire-level walk over each message's fields notes
where each packed array lies in one joined buffer (a few tag reads per message); then every
array of every episode is decoded in a handful of numpy operations: gather the bytes, find the
varint ends (bytes < 0x80), and sum the 7-bit groups. Any message with an unexpected shape (an
unknown wire type, an unpacked repeated field) makes :func:`decode_episodes` return None, and the
caller decodes with the Protobuf runtime instead, so this is an accelerator, never a second truth.
"""
from __future__ import annotations

import struct

import numpy as np

from . import schema as S

# (sub-message, field number) -> column name, for packed repeated varint fields
_STEPS_INT = {1: "states", 2: "actions", 4: "flags"}
_REC_INT = {1: "r_step", 2: "r_state", 3: "r_action", 4: "r_picture", 5: "r_predicted", 6: "r_true"}
_UN_INT = {1: "u_step", 2: "u_state", 3: "u_action", 4: "u_source"}
INT_COLUMNS = tuple(_STEPS_INT.values()) + tuple(_REC_INT.values()) + tuple(_UN_INT.values())
FLOAT_COLUMNS = ("rewards", "scores", "q_values")


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


def _walk(buf: bytes, start: int, end: int, packed: dict[int, str], floats: dict[int, str],
          spans: dict[str, list], scalars: dict[int, str] | None, out_scalars: dict, owner: int) -> None:
    """Note the spans (start, end) of the packed fields of one (sub)message."""
    pos = start
    while pos < end:
        tag, pos = _varint(buf, pos)
        field, wt = tag >> 3, tag & 7
        if wt == 2:
            ln, pos = _varint(buf, pos)
            name = packed.get(field) or floats.get(field)
            if name is not None:
                spans[name].append((pos, pos + ln, owner))
            elif scalars is not None and field in scalars:
                raise _Unexpected("length-delimited scalar")
            pos += ln
        elif wt == 0:
            value, pos = _varint(buf, pos)
            if field in packed or field in floats:
                raise _Unexpected("unpacked repeated field")
            if scalars is not None and field in scalars:
                out_scalars[scalars[field]] = value
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
    # per message: count terminators inside its spans
    lengths = spans[:, 1] - spans[:, 0]
    cum = np.concatenate(([0], np.cumsum(term)))
    bounds = np.concatenate(([0], np.cumsum(lengths)))
    per_span = cum[bounds[1:]] - cum[bounds[:-1]]
    counts = np.bincount(owner, weights=per_span, minlength=n_msgs).astype(np.int64)
    return values, counts


def _decode_floats(raw: np.ndarray, spans: np.ndarray, n_msgs: int, owner: np.ndarray):
    data = _gather(raw, spans)
    if data.size % 4:
        raise _Unexpected("packed float length")
    lengths = (spans[:, 1] - spans[:, 0]) // 4 if len(spans) else np.zeros(0, np.int64)
    counts = np.bincount(owner, weights=lengths, minlength=n_msgs).astype(np.int64)
    return data.view("<f4"), counts


def decode_episodes(messages: list[bytes]) -> dict | None:
    """Decode Episode messages into flat columns, or None if any message has an unexpected shape.

    Returns a dict with ``run``, ``episode``, ``n_categories``, ``n_actions`` (per message),
    the int and float columns of :data:`INT_COLUMNS` / :data:`FLOAT_COLUMNS` (all messages
    concatenated) with their per-message ``counts``, and ``summaries`` (raw summary bytes)."""
    n = len(messages)
    buf = b"".join(messages)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum([len(m) for m in messages], out=offsets[1:])
    spans: dict[str, list] = {k: [] for k in INT_COLUMNS + FLOAT_COLUMNS}
    run = np.zeros(n, np.int64)
    episode = np.zeros(n, np.int64)
    n_cat = np.zeros(n, np.int64)
    n_act = np.zeros(n, np.int64)
    summaries: list[bytes] = []
    top_scalars = {1: "run", 2: "episode", 7: "n_actions"}
    try:
        for i in range(n):
            pos, end = int(offsets[i]), int(offsets[i + 1])
            scal: dict[str, int] = {}
            summary = b""
            while pos < end:
                tag, pos = _varint(buf, pos)
                field, wt = tag >> 3, tag & 7
                if wt == 0:
                    value, pos = _varint(buf, pos)
                    if field in top_scalars:
                        scal[top_scalars[field]] = value
                    elif field == 8:
                        raise _Unexpected("unpacked q_values")
                elif wt == 2:
                    ln, pos = _varint(buf, pos)
                    sub_end = pos + ln
                    if field == 3:
                        _walk(buf, pos, sub_end, _STEPS_INT, {3: "rewards"}, spans, None, scal, i)
                    elif field == 4:
                        rs: dict[str, int] = {}
                        _walk(buf, pos, sub_end, _REC_INT, {8: "scores"}, spans, {7: "n_categories"}, rs, i)
                        n_cat[i] = rs.get("n_categories", 0)
                    elif field == 5:
                        _walk(buf, pos, sub_end, _UN_INT, {}, spans, None, scal, i)
                    elif field == 6:
                        summary = buf[pos:sub_end]
                    elif field == 8:
                        spans["q_values"].append((pos, sub_end, i))
                    pos = sub_end
                elif wt == 1:
                    pos += 8
                elif wt == 5:
                    pos += 4
                else:
                    raise _Unexpected(f"wire type {wt}")
            if pos != end:
                raise _Unexpected("field runs past the message")
            run[i] = scal.get("run", 0)
            episode[i] = scal.get("episode", 0)
            n_act[i] = scal.get("n_actions", 0)
            summaries.append(summary)
        raw = np.frombuffer(buf, dtype=np.uint8)
        out: dict = {"run": run, "episode": episode, "n_categories": n_cat, "n_actions": n_act,
                     "summaries": summaries, "counts": {}}
        for k in INT_COLUMNS + FLOAT_COLUMNS:
            sp = np.array(spans[k], dtype=np.int64).reshape(-1, 3)
            decode = _decode_varints if k in INT_COLUMNS else _decode_floats
            out[k], out["counts"][k] = decode(raw, sp[:, :2], n, sp[:, 2])
    except (_Unexpected, IndexError, struct.error):
        return None
    return out


def decode_summaries(summaries: list[bytes]) -> tuple[dict[str, np.ndarray], list[dict[str, float]]]:
    """The per-episode summary columns (through the Protobuf runtime: six scalars a message)."""
    cols = {k: [] for k in ("steps", "collisions", "return_", "reached_goal", "prevented", "epsilon")}
    extras: list[dict[str, float]] = []
    parse = S.EpisodeSummary.FromString
    for data in summaries:
        sm = parse(data)
        cols["steps"].append(sm.steps)
        cols["collisions"].append(sm.collisions)
        cols["return_"].append(sm.return_)
        cols["reached_goal"].append(sm.reached_goal)
        cols["prevented"].append(sm.prevented)
        cols["epsilon"].append(sm.epsilon)
        extras.append(dict(sm.extra) if len(sm.extra) else {})
    return cols, extras
