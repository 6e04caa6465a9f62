"""Protobuf wire-format pieces for the vectorised Episode encoder (``writer.encode_staged``).

Why hand-written: the upb ``Message`` API costs 85-100 us per episode (a Python int per packed
element), which at paper scale would make the recording a large part of the trial time. Packed
repeated fields are just a length-prefixed run of varints (or raw little-endian floats), which
numpy encodes for a whole batch of episodes in one pass. The output is byte-for-byte what
``Episode.SerializeToString(deterministic=True)`` produces for the same values (tests check it on
many episodes), so every Protobuf decoder (ours, Foxglove, Rerun) reads it with the schema in
:mod:`.schema`.

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


_ZERO_DOUBLE = bytes(8)


def double_field(field: int, x: float) -> bytes:
    """A double; proto3 omits one equal to its default 0.0 (but keeps -0.0, whose bits differ)."""
    packed = _DOUBLE.pack(x)
    return key(field, _I64) + packed if packed != _ZERO_DOUBLE else b""


def map_entry_string_double(k: str, v: float) -> bytes:
    """A ``map<string, double>`` entry; like upb, both key and value are always written."""
    kb = k.encode("utf-8")
    return key(1, _LEN) + varint(len(kb)) + kb + key(2, _I64) + _DOUBLE.pack(v)
