"""Vectorised Protobuf wire encoding of the :data:`~pipeline.records.schema.Episode` message.

Why hand-written: the upb ``Message`` API costs 40-60 us per episode (a Python list per packed
field), which at paper scale would make the recording a large part of the trial time. Packed
repeated fields are just a length-prefixed run of varints (or raw little-endian floats), which
numpy encodes in one pass. The output is byte-for-byte what ``Episode.SerializeToString
(deterministic=True)`` produces for the same values (tests check it on many episodes), so every
Protobuf decoder (ours, Foxglove, Rerun) reads it with the schema in :mod:`.schema`.

Encoding rules used (proto3): fields in field-number order; scalars equal to their default and
empty repeated fields are omitted; ``int32`` negatives are 10-byte sign-extended varints.
"""
from __future__ import annotations

import struct

import numpy as np

_VARINT = 0
_I64 = 1
_LEN = 2
_DOUBLE = struct.Struct("<d")
_SHIFTS = np.arange(0, 70, 7, dtype=np.uint64)  # 10 groups of 7 bits cover 64 bits


def varint(n: int) -> bytes:
    """One varint (``n`` >= 0, or a negative int32/int64 as its 64-bit two's complement)."""
    if n < 0:
        n += 1 << 64
    if n < 0x80:
        return bytes((n,))
    out = bytearray()
    while n >= 0x80:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def packed_varints(a: np.ndarray) -> bytes:
    """The payload of a packed repeated varint field holding the integers ``a``."""
    if a.dtype.kind == "u":
        u = a.astype(np.uint64, copy=False)
    else:
        u = a.astype(np.int64, copy=False).view(np.uint64)
    if len(u) == 0:
        return b""
    top = int(u.max())
    if top < 0x80:
        return u.astype(np.uint8).tobytes()
    groups = (u[:, None] >> _SHIFTS[None, :]) & np.uint64(0x7F)  # (n, 10)
    # bytes needed per value: 1 + index of the highest non-zero 7-bit group
    nz = groups != 0
    nbytes = np.where(nz.any(axis=1), 10 - np.argmax(nz[:, ::-1], axis=1), 1)
    width = int(nbytes.max())
    groups = groups[:, :width].astype(np.uint8)
    k = np.arange(width)
    groups[k[None, :] < (nbytes[:, None] - 1)] |= 0x80
    return groups[k[None, :] < nbytes[:, None]].tobytes()


def key(field: int, wire_type: int) -> bytes:
    return varint((field << 3) | wire_type)


_VARINTS = [varint(i) for i in range(1 << 14)]  # lengths and small scalars: a table lookup


def varint_small(n: int) -> bytes:
    return _VARINTS[n] if n < 16384 else varint(n)


KEY_EPISODE_STEPS = bytes(((3 << 3) | _LEN,))
KEY_EPISODE_SUMMARY = bytes(((6 << 3) | _LEN,))


_THRESHOLDS = np.array([1 << (7 * i) for i in range(1, 10)], dtype=np.uint64)


def varints_with_ends(a: np.ndarray) -> tuple[bytes, np.ndarray]:
    """Varint encoding of the int64 values ``a`` (negatives as 10-byte two's complement) and the
    byte offsets ``[0, end of value 0, end of value 1, ...]``. One vector pass per byte level."""
    if len(a) == 0:
        return b"", np.zeros(1, np.int64)
    u = a.astype(np.int64, copy=False).view(np.uint64)
    nbytes = np.searchsorted(_THRESHOLDS, u, side="right") + 1
    cum = np.concatenate(([0], np.cumsum(nbytes)))
    out = np.empty(int(cum[-1]), dtype=np.uint8)
    out[cum[:-1]] = (u & np.uint64(0x7F)).astype(np.uint8)
    for level in range(1, int(nbytes.max())):
        idx = np.flatnonzero(nbytes > level)
        out[cum[idx] + level - 1] |= 0x80  # the previous byte continues
        out[cum[idx] + level] = ((u[idx] >> np.uint64(7 * level)) & np.uint64(0x7F)).astype(np.uint8)
    return out.tobytes(), cum


_LEN_KEYS = [bytes(((f << 3) | _LEN,)) for f in range(16)]
_VARINT_KEYS = [bytes(((f << 3) | _VARINT,)) for f in range(16)]


def len_field(field: int, payload: bytes) -> bytes:
    """A length-delimited field (packed array, string, bytes, sub-message); empty -> omitted."""
    if not payload:
        return b""
    return _LEN_KEYS[field] + varint_small(len(payload)) + payload


def uint_field(field: int, n: int) -> bytes:
    return _VARINT_KEYS[field] + (varint_small(n) if 0 <= n < 16384 else varint(n)) if n else b""


def double_field(field: int, x: float) -> bytes:
    # proto3 omits a double equal to its default 0.0 (but keeps -0.0, whose bits differ)
    return key(field, _I64) + _DOUBLE.pack(x) if _DOUBLE.pack(x) != b"\0" * 8 else b""


def packed_int_field(field: int, a: np.ndarray) -> bytes:
    return len_field(field, packed_varints(a)) if len(a) else b""


def packed_float_field(field: int, a: np.ndarray) -> bytes:
    return len_field(field, a.astype("<f4", copy=False).tobytes()) if len(a) else b""


def string_field(field: int, s: str) -> bytes:
    return len_field(field, s.encode("utf-8"))


def map_entry_string_double(k: str, v: float) -> bytes:
    """A ``map<string, double>`` entry; like upb, both key and value are always written."""
    kb = k.encode("utf-8")
    return key(1, _LEN) + varint(len(kb)) + kb + key(2, _I64) + _DOUBLE.pack(v)
