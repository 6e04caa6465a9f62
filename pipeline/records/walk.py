"""Reading a damaged or truncated MCAP record file front to back (docs/records.md "Damaged and
truncated files"): mcap's ``StreamReader(emit_chunks=True)`` and ``breakup_chunk(validate_crc=True)``,
a new stream reader after each damaged record (where the chunk index or a valid record says reading
can go on), then every chunk the index names that was never reached.
"""

from __future__ import annotations

import contextlib
import io
import re
import struct
from operator import attrgetter

from mcap.opcode import Opcode
from mcap.records import Chunk, DataEnd, MessageIndex, Metadata
from mcap.stream_reader import StreamReader, breakup_chunk

from . import schema as S
from .scanned import DATA_END_HEAD, Damage, Scan, channel_kind, check_data_end, file_record

_DATA_RECORDS = {
    Opcode.HEADER,
    Opcode.SCHEMA,
    Opcode.CHANNEL,
    Opcode.MESSAGE,
    Opcode.CHUNK,
    Opcode.MESSAGE_INDEX,
    Opcode.METADATA,
    Opcode.ATTACHMENT,
    Opcode.DATA_END,
}  # the records a data section may hold
_NAMES = {o: f"a {o.name.lower().replace('_', ' ')} record" for o in Opcode}
_RESYNC = re.compile(rb"[\x06\x0c\x0f]")  # chunk, metadata, data end: where reading can start again
_HEAD, _TIMES = struct.Struct("<BQ"), struct.Struct("<QQ")
_SPAN = attrgetter("message_start_time", "message_end_time")  # of a chunk or a chunk index


def walk(data: bytes, out: Scan, limit: int, time_range) -> None:
    """Read ``data`` up to byte ``limit`` into ``out``, front to back; then what was lost."""
    _Walk(data, out, limit, time_range).run()


class _Walk:
    """One front-to-back read: where it is, the chunks met and reached, and the damaged chunk just
    read (its message index, when intact, says what it held)."""

    def __init__(self, data: bytes, out: Scan, limit: int, time_range) -> None:
        self.data, self.out, self.limit, self.time_range = data, out, limit, time_range
        self.n, self.f = len(data), io.BytesIO(data)
        self.chunks = 0  # chunks met
        self.lost: Damage | None = None  # the damaged chunk just read
        self.visited: set[int] = set()  # chunks reached
        summary = out.summary
        indexes = (
            sorted(summary.chunk_indexes, key=attrgetter("chunk_start_offset")) if summary else []
        )
        self.indexed = {c.chunk_start_offset: c for c in indexes}
        self.number = {c.chunk_start_offset: k for k, c in enumerate(indexes, 1)}
        self.of = f" of {len(self.indexed)}" if summary is not None else ""
        if summary is not None:
            out.schemas, out.channels = dict(summary.schemas), dict(summary.channels)

    def run(self) -> None:
        pos = 8
        while pos is not None and pos < self.limit:
            pos = self._read_from(pos)
        self._unreached()

    def _read_from(self, start: int) -> int | None:
        """Records from byte ``start`` on, until the data end or a damaged record; returns where
        reading goes on after the damage, or None."""
        self.f.seek(start)
        try:
            reader = StreamReader(
                self.f, skip_magic=True, emit_chunks=True, record_size_limit=self.n
            )
            for rec in reader.records:
                end = self.f.tell()
                if self._record(rec, start, end):
                    return None
                start = end
        except Exception as e:
            why = (
                str(e)
                if isinstance(e, ValueError) and str(e)
                else f"{type(e).__name__}: {e}".rstrip(": ")
            )
            return self._damaged(start, why)
        return None

    def _record(self, rec, start: int, end: int) -> bool:
        """File one record read intact from ``start`` to ``end``; True at the data-end record."""
        data, out, c = self.data, self.out, self.indexed.get(start)
        if data[start] not in _DATA_RECORDS or (c and end - start != c.chunk_length):
            raise ValueError(
                "its record header disagrees with " + ("the chunk index" if c else "its contents")
            )
        if isinstance(rec, MessageIndex):
            if self.lost is not None and (kind := channel_kind(out, rec.channel_id)):
                self.lost.held.setdefault(kind, []).extend(t for t, _ in rec.records)
        elif isinstance(rec, DataEnd):
            if data[start : start + 9] != DATA_END_HEAD:
                raise ValueError("its record header disagrees with its contents")
            check_data_end(data, out, rec.data_section_crc, start, self.time_range)
            return True
        elif not isinstance(rec, Chunk):
            self.lost = None
            file_record(out, rec, self.time_range)
        elif end - start != _chunk_size(rec):
            raise ValueError("bad chunk header: its data length disagrees with its record length")
        else:
            self.chunks += 1
            self.visited.add(start)
            why = file_record(out, rec, self.time_range)
            self.lost = self._damaged_chunk(start, why, _SPAN(rec)) if why else None
        return False

    def _damaged_chunk(self, start: int, why: str, span, went_on: str = "") -> Damage:
        self.visited.add(start)
        number = self.number.get(start, self.chunks)
        self.out.damage.append(
            Damage(
                "chunk",
                f"chunk {number}{self.of} damaged ({why}) at byte {start}{went_on}",
                span,
            )
        )
        return self.out.damage[-1]

    def _damaged(self, start: int, why: str) -> int | None:
        """Note the damaged record at ``start``; returns where reading goes on, or None."""
        data, n = self.data, self.n
        if start >= n:
            self.out.damage.append(
                Damage(
                    "truncated",
                    f"the file is truncated: it ends after {n} bytes at a record "
                    "boundary, before its data-end record; anything written after "
                    "that and the summary section are lost",
                )
            )
            return None
        if start in self.indexed:  # the chunk index says where the next record starts
            self.lost = self._damaged_chunk(start, why, _SPAN(self.indexed[start]))
            return start + self.indexed[start].chunk_length
        opcode, length = _HEAD.unpack_from(data, start) if start + 9 <= n else (data[start], n)
        span = (
            _TIMES.unpack_from(data, start + 9)
            if opcode == Opcode.CHUNK and start + 25 <= n
            else None
        )
        span = span if span and span[0] <= span[1] else None
        pos = _find_next(data, start + 1, self.limit)
        went_on = f"; reading went on at byte {pos}" if pos else ""
        if pos is None and start + 9 + length > n:
            self._truncated_inside(start, opcode, length, span)
        elif opcode == Opcode.CHUNK:
            self.chunks += 1
            self.lost = self._damaged_chunk(start, why, span, went_on)
        else:
            self.out.damage.append(
                Damage("bytes", f"a damaged record ({why}) at byte {start} was skipped{went_on}")
            )
        return pos

    def _truncated_inside(self, start: int, opcode: int, length: int, span) -> None:
        """The file ends inside the record at ``start``."""
        name = _NAMES.get(opcode, f"a record (opcode {opcode:#x})")
        if opcode == Opcode.CHUNK:
            name = f"chunk {self.chunks + 1}, of {length} bytes at byte {start}"
            if span:
                (r0, e0, _), (r1, e1, _) = map(S.split_log_time, span)
                name += f", holding messages stamped run {r0} episode {e0}" + (
                    "" if (r0, e0) == (r1, e1) else f" to run {r1} episode {e1}"
                )
        self.out.damage.append(
            Damage(
                "truncated",
                f"the file is truncated: it ends {self.n - start - 9} bytes into "
                f"{name}; that record, anything after it and the summary "
                "section are lost",
                span,
            )
        )

    def _unreached(self) -> None:
        """Every chunk the index names that reading never reached."""
        for start, c in self.indexed.items():
            if start not in self.visited:
                self.out.damage.append(
                    Damage(
                        "chunk",
                        f"chunk {self.number[start]}{self.of} at byte {start} was not reached "
                        "(the records before it are damaged)",
                        _SPAN(c),
                    )
                )


def _chunk_size(rec: Chunk) -> int:
    """The bytes a chunk record takes: its header, then its fields (times, sizes, CRC, compression, data)."""
    return 9 + 8 * 3 + 4 + 4 + len(rec.compression) + 8 + len(rec.data)


def _find_next(data: bytes, start: int, limit: int) -> int | None:
    """The first offset >= ``start`` where a valid chunk (CRC checked), metadata or data-end record starts."""
    for m in _RESYNC.finditer(data, start, limit):
        with contextlib.suppress(Exception):
            size = 9 + _HEAD.unpack_from(data, p := m.start())[1]
            rec = (
                next(
                    StreamReader(
                        io.BytesIO(data[p : p + size]), skip_magic=True, emit_chunks=True
                    ).records
                )
                if p + size <= limit
                else None
            )
            if isinstance(rec, Chunk) and rec.uncompressed_crc and _chunk_size(rec) == size:
                breakup_chunk(rec, validate_crc=True)
                return p
            if isinstance(rec, Metadata) or (isinstance(rec, DataEnd) and size == 13):
                return p
    return None
