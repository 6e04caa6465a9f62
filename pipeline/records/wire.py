"""Protobuf wire-format pieces for the vectorised EpisodeBatch encoder (:mod:`.batch`).

Why hand-written: the upb ``Message`` API turns every packed element into a Python int (about
1 us each), which at paper scale would make the recording a large part of the trial time. Packed
repeated fields are just a length-prefixed run of varints (or raw little-endian floats), which
numpy encodes for a whole batch in one pass. The output is byte-for-byte what
``EpisodeBatch.SerializeToString(deterministic=True)`` produces for the same values (tests check),
so every Protobuf decoder (ours, Foxglove, Rerun) reads it with the schema in :mod:`.schema`.

Encoding rules used (proto3): fields in field-number order; scalars equal to their default and
empty repeated fields are omitted; ``int32`` negatives are 10-byte sign-extended varints.
"""
from __future__ import annotations

import numpy as np

_VARINT = 0
_LEN = 2


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


VARINT_TABLE = [varint(i) for i in range(1 << 14)]  # lengths, small scalars and short arrays: a lookup
_VARINTS = VARINT_TABLE


def varint_small(n: int) -> bytes:
    return _VARINTS[n] if n < 16384 else varint(n)


_THRESHOLDS = np.array([1 << (7 * i) for i in range(1, 10)], dtype=np.uint64)


def varints(a: np.ndarray) -> tuple[bytes, np.ndarray | None]:
    """Varint encoding of the int64 values ``a`` (negatives as 10-byte two's complement) and the
    byte offsets ``[0, end of value 0, end of value 1, ...]``, or None when every value takes one
    byte (offsets = value indices). One vector pass per byte level; values in [0, 2^14), the usual
    case (cells, steps, picture ids), take a two-level shortcut."""
    if len(a) == 0:
        return b"", None
    lo, hi = int(a.min()), int(a.max())
    if lo >= 0 and hi < 0x80:
        return a.astype(np.uint8).tobytes(), None
    if lo >= 0 and hi < 0x4000:  # one or two bytes: interleave (low | continuation, high), drop unused highs
        two = a >= 0x80
        pairs = np.empty((len(a), 2), np.uint8)
        pairs[:, 0] = (a & 0x7F) | (two.view(np.uint8) << 7)
        pairs[:, 1] = a >> 7
        keep = np.empty((len(a), 2), bool)
        keep[:, 0] = True
        keep[:, 1] = two
        cum = np.empty(len(a) + 1, np.int64)
        cum[0] = 0
        np.cumsum(keep[:, 1], out=cum[1:])
        cum[1:] += np.arange(1, len(a) + 1)
        return pairs.ravel()[keep.ravel()].tobytes(), cum
    return varints_with_ends(a)


def varints_with_ends(a: np.ndarray) -> tuple[bytes, np.ndarray]:
    """:func:`varints` for any int64 values, always with the offsets."""
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
