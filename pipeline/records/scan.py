"""What survives of an MCAP record file, read through the mcap package (docs/records.md "Damaged and truncated
files"): with mcap's seeking reader when its summary is intact, else (or when that finds damage) front to back with
``StreamReader(emit_chunks=True)`` and ``breakup_chunk(validate_crc=True)``, a new stream reader after each damaged
record. Each damaged or missing part is a :class:`Damage`; a file with nothing to read raises :class:`RecordsError`.
"""

from __future__ import annotations

import contextlib
import io
import re
import struct
import zlib
from dataclasses import dataclass, field
from operator import attrgetter
from pathlib import Path

from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE, make_reader
from mcap.records import Channel, Chunk, DataEnd, Header, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.summary import Summary

from pipeline.errors import UserError

from . import schema as S

MAGIC = b"\x89MCAP0\r\n"
#: The writer registers these first, in this order, in every file (tested): channel id -> (topic,
#: schema id, message class); used when every copy of a file's channel definitions is lost.
WRITER_CHANNELS = {1: (S.TOPIC_EPISODES, 1, S.EpisodeBatch)}
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
_HEAD, _TIMES, _FOOTER = struct.Struct("<BQ"), struct.Struct("<QQ"), struct.Struct("<BQQQI")
_DATA_END_HEAD = _HEAD.pack(Opcode.DATA_END, 4)  # a data-end record's opcode and length
_SPAN = attrgetter("message_start_time", "message_end_time")  # of a chunk or a chunk index
_PICTURES = (S.TOPIC_PICTURES, S.TOPIC_SUPPORT)  # stamped 0: read whatever the time range
_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"PK\x03\x04", "a zip archive"),
    (b"\x1f\x8b", "a gzip file"),
    (b"\x28\xb5\x2f\xfd", "a zstd file"),
    (b"SQLite format 3\x00", "an SQLite database"),
    (b"RRF", "a Rerun .rrd file"),
)


class RecordsError(UserError):
    """A record file that cannot be read at all; the message names the file and the problem."""


@dataclass
class Damage:
    """One damaged or missing part of a file."""

    kind: str  # "chunk", "bytes", "metadata", "summary", "decode", "data" (damage); "truncated" (ends early)
    what: str  # a sentence naming the part, where it is and what is wrong with it
    span: tuple[int, int] | None = None  # log times of the messages it held, when known
    held: dict[str, list[int]] = field(
        default_factory=dict
    )  # a lost chunk's message index: kind -> log times
    lost: list = field(
        default_factory=list
    )  # (run, first, last) episode ranges, filled by the loss accounting


@dataclass
class Scan:
    """What was read from one file. ``messages``: topic -> list of (log_time, data)."""

    path: Path
    library: str | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: dict[str, list[tuple[int, bytes]]] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    damage: list[Damage] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # recovered, nothing lost
    summary: Summary | None = None  # the summary section, when intact
    complete: bool = False  # read through its intact summary, nothing damaged
    dropped: int = 0  # messages whose channel definition is lost everywhere


def message_kind(topic: str) -> str | None:
    """How a lost message is counted: episode batches, pictures, support pictures."""
    return (
        "episode batches"
        if topic == S.TOPIC_EPISODES
        else (
            "pictures"
            if topic.startswith(S.TOPIC_PICTURES + "/")
            else "support pictures"
            if topic.startswith(S.TOPIC_SUPPORT + "/")
            else None
        )
    )


def scan(path: str | Path, *, time_range: tuple[int, int] | None = None) -> Scan:
    """Every intact record of ``path``; ``time_range`` (ns, end exclusive) leaves out the messages
    outside it, and their chunks unread (pictures, stamped 0, are always read)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except IsADirectoryError:
        raise RecordsError(f"{path}: is a folder, not a record file") from None
    except OSError as e:
        raise RecordsError(f"{path}: cannot be read ({e.strerror or e})") from None
    if data[:8] != MAGIC:
        what = next(
            (f"it is {w}" for sig, w in _SIGNATURES if data.startswith(sig)),
            "it does not start with the MCAP magic bytes",
        )
        raise RecordsError(
            f"{path}: empty file (0 bytes): not an MCAP record file"
            if not data
            else f"{path}: truncated after {len(data)} bytes, inside the MCAP magic bytes: nothing to read"
            if len(data) < 8 and MAGIC.startswith(data)
            else f"{path}: not an MCAP file ({what})"
        )
    out, reader = Scan(path), make_reader(io.BytesIO(data), validate_crcs=True)
    end = _summary(data, out, reader)
    if out.summary is not None:
        with contextlib.suppress(Exception):  # damage found: read it record by record
            return _read_indexed(data, path, reader, end, time_range)
    _walk(data, out, end, time_range)
    return out


def _summary(data: bytes, out: Scan, reader) -> int:
    """The summary section, if intact (CRC checked), as ``out.summary``; returns where the data section ends."""
    foot = len(data) - 8 - FOOTER_SIZE
    if foot < 8 or data[-8:] != MAGIC:
        return len(data)
    opcode, length, start, _, crc = _FOOTER.unpack_from(data, foot)
    if (opcode, length) != (Opcode.FOOTER, FOOTER_SIZE - 9):
        out.damage.append(
            Damage(
                "summary",
                f"the footer at byte {foot} is damaged; the file was read without its "
                "summary section",
            )
        )
    elif start:
        problem = (
            "names a summary section outside the file"
            if not 8 < start <= foot
            else "CRC mismatch"
            if crc and zlib.crc32(data[start : foot + FOOTER_SIZE - 4]) != crc
            else None
        )
        try:
            out.summary = None if problem else reader.get_summary()
        except Exception as e:
            problem = f"it does not parse ({type(e).__name__}: {e})"
        if problem:
            out.damage.append(
                Damage(
                    "summary",
                    f"the summary section at byte {start} is damaged ({problem}); the "
                    "file was read without it",
                )
            )
    return len(data) if out.summary is None else start


def _read_indexed(data: bytes, path: Path, reader, end: int, time_range) -> Scan:
    """A file with an intact summary, through mcap's seeking reader; raises on any damage found."""
    summary = reader.get_summary()
    out = Scan(
        path, schemas=dict(summary.schemas), channels=dict(summary.channels), summary=summary
    )
    topics = {c.topic for c in summary.channels.values()}
    pictures = {t for t in topics if t.startswith(_PICTURES)}
    queries = (
        [{}]
        if time_range is None
        else [
            {"topics": pictures},
            {
                "topics": topics - pictures,
                "starting_at": time_range[0],
                "ending_before": time_range[1],
            },
        ]
    )
    messages = (
        m for query in queries for _, _, m in reader.iter_messages(log_time_order=False, **query)
    )
    for rec in (reader.get_header(), *reader.iter_metadata(), *messages):
        _file(out, rec, None)
    if data[end - 13 : end - 4] != _DATA_END_HEAD:
        raise TypeError("no data-end record before the summary")
    _data_end(data, out, int.from_bytes(data[end - 4 : end], "little"), end - 13, time_range)
    out.complete = not out.damage
    return out


def _walk(data: bytes, out: Scan, limit: int, time_range) -> None:  # noqa: PLR0915 (to split)
    """Front to back with mcap's stream reader, a new one after each damaged record; then what was lost."""
    n, f, pos = len(data), io.BytesIO(data), 8
    chunks, lost, visited = (
        0,
        None,
        set(),
    )  # chunks met, the damaged chunk just read, chunks reached
    indexes = (
        sorted(out.summary.chunk_indexes, key=attrgetter("chunk_start_offset"))
        if out.summary
        else []
    )
    indexed = {c.chunk_start_offset: c for c in indexes}
    number = {c.chunk_start_offset: k for k, c in enumerate(indexes, 1)}
    of = f" of {len(indexed)}" if out.summary is not None else ""
    if out.summary is not None:
        out.schemas, out.channels = dict(out.summary.schemas), dict(out.summary.channels)

    def damaged_chunk(start: int, why: str, span, went_on: str = "") -> Damage:
        visited.add(start)
        out.damage.append(
            Damage(
                "chunk",
                f"chunk {number.get(start, chunks)}{of} damaged ({why}) at byte {start}{went_on}",
                span,
            )
        )
        return out.damage[-1]

    while pos is not None and pos < limit:
        f.seek(start := pos)
        pos = None
        try:
            for rec in StreamReader(
                f, skip_magic=True, emit_chunks=True, record_size_limit=n
            ).records:
                end, c = f.tell(), indexed.get(start)
                if data[start] not in _DATA_RECORDS or (c and end - start != c.chunk_length):
                    raise ValueError(
                        "its record header disagrees with "
                        + ("the chunk index" if c else "its contents")
                    )
                if isinstance(rec, MessageIndex):
                    if lost is not None and (
                        kind := _kind(out, rec.channel_id)
                    ):  # what the damaged chunk held
                        lost.held.setdefault(kind, []).extend(t for t, _ in rec.records)
                elif isinstance(rec, DataEnd):
                    if data[start : start + 9] != _DATA_END_HEAD:
                        raise ValueError("its record header disagrees with its contents")
                    _data_end(data, out, rec.data_section_crc, start, time_range)
                    break
                elif not isinstance(rec, Chunk):
                    lost = None
                    _file(out, rec, time_range)
                elif end - start != _chunk_size(rec):
                    raise ValueError(
                        "bad chunk header: its data length disagrees with its record length"
                    )
                else:
                    chunks += 1
                    visited.add(start)
                    why = _file(out, rec, time_range)
                    lost = damaged_chunk(start, why, _SPAN(rec)) if why else None
                start = end
        except Exception as e:
            why = (
                str(e)
                if isinstance(e, ValueError) and str(e)
                else f"{type(e).__name__}: {e}".rstrip(": ")
            )
            if start >= n:
                out.damage.append(
                    Damage(
                        "truncated",
                        f"the file is truncated: it ends after {n} bytes at a record "
                        "boundary, before its data-end record; anything written after "
                        "that and the summary section are lost",
                    )
                )
            elif start in indexed:  # the chunk index says where the next record starts
                lost = damaged_chunk(start, why, _SPAN(indexed[start]))
                pos = start + indexed[start].chunk_length
            else:
                opcode, length = (
                    _HEAD.unpack_from(data, start) if start + 9 <= n else (data[start], n)
                )
                span = (
                    _TIMES.unpack_from(data, start + 9)
                    if opcode == Opcode.CHUNK and start + 25 <= n
                    else None
                )
                span = span if span and span[0] <= span[1] else None
                pos = _find_next(data, start + 1, limit)
                went_on = f"; reading went on at byte {pos}" if pos else ""
                if pos is None and start + 9 + length > n:
                    name = _NAMES.get(opcode, f"a record (opcode {opcode:#x})")
                    if opcode == Opcode.CHUNK:
                        name = f"chunk {chunks + 1}, of {length} bytes at byte {start}"
                        if span:
                            (r0, e0, _), (r1, e1, _) = map(S.split_log_time, span)
                            name += f", holding messages stamped run {r0} episode {e0}" + (
                                "" if (r0, e0) == (r1, e1) else f" to run {r1} episode {e1}"
                            )
                    out.damage.append(
                        Damage(
                            "truncated",
                            f"the file is truncated: it ends {n - start - 9} bytes into "
                            f"{name}; that record, anything after it and the summary "
                            "section are lost",
                            span,
                        )
                    )
                elif opcode == Opcode.CHUNK:
                    chunks += 1
                    lost = damaged_chunk(start, why, span, went_on)
                else:
                    out.damage.append(
                        Damage(
                            "bytes",
                            f"a damaged record ({why}) at byte {start} was skipped{went_on}",
                        )
                    )
    for start, c in indexed.items():
        if start not in visited:
            out.damage.append(
                Damage(
                    "chunk",
                    f"chunk {number[start]}{of} at byte {start} was not reached (the "
                    "records before it are damaged)",
                    _SPAN(c),
                )
            )


def _kind(out: Scan, cid: int) -> str | None:
    """How the messages of channel ``cid`` are counted (:func:`message_kind`), its definition lost or not."""
    ours = out.library == S.LIBRARY
    topic = (
        out.channels[cid].topic
        if cid in out.channels
        else WRITER_CHANNELS.get(cid, ("",))[0]
        if ours
        else ""
    )
    return (
        message_kind(topic)
        if topic
        else "pictures"
        if ours
        else "messages of channels whose definitions were lost"
    )


def _writer_channel(out: Scan, cid: int) -> Channel | None:
    """Channel ``cid`` of this writer's fixed layout, for a file of its whose definition of it was lost."""
    if out.library != S.LIBRARY or cid not in WRITER_CHANNELS:
        return None
    topic, sid, cls = WRITER_CHANNELS[cid]
    out.channels[cid] = Channel(
        id=cid, topic=topic, message_encoding="protobuf", schema_id=sid, metadata={}
    )
    out.schemas.setdefault(
        sid,
        Schema(
            id=sid,
            name=cls.DESCRIPTOR.full_name,
            encoding="protobuf",
            data=S.file_descriptor_set(cls),
        ),
    )
    out.notes.append(
        f"the definition of channel {topic} was lost with the damaged part; taken from this writer's "
        f"fixed channel layout ({S.LIBRARY})"
    )
    return out.channels[cid]


def _file(out: Scan, rec, time_range) -> str | None:
    """File one record (a chunk: its records, unless outside ``time_range``); returns why a chunk is damaged."""
    if isinstance(rec, Message):
        ch = out.channels.get(rec.channel_id) or _writer_channel(out, rec.channel_id)
        if ch is None:
            out.dropped += 1
        elif (
            time_range is None
            or time_range[0] <= rec.log_time < time_range[1]
            or ch.topic.startswith(_PICTURES)
        ):
            out.messages.setdefault(ch.topic, []).append((rec.log_time, rec.data))
    elif isinstance(rec, Chunk):
        if (
            time_range is not None
            and out.channels
            and rec.message_start_time != 0
            and (rec.message_end_time < time_range[0] or rec.message_start_time >= time_range[1])
        ):
            return None
        try:
            records = breakup_chunk(rec, validate_crc=True)
        except Exception as e:
            bad = type(e).__module__.startswith(("zstandard", "lz4")) or isinstance(e, RuntimeError)
            return (
                "CRC mismatch"
                if isinstance(e, CRCValidationError)
                else f"bad decompression ({type(e).__name__}: {e})"
                if bad
                else "bad record lengths"
            )
        for r in records:
            _file(out, r, time_range)
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec
    elif isinstance(rec, Metadata):
        out.metadata[rec.name] = dict(rec.metadata)
    elif isinstance(rec, Header):
        out.library = rec.library
    return None


def _data_end(data: bytes, out: Scan, crc: int, start: int, time_range) -> None:
    """The data section's CRC, ``crc`` (on a full read of a file with no other damage), and a lost summary."""
    if (
        crc
        and time_range is None
        and not out.damage
        and zlib.crc32(memoryview(data)[:start]) != crc
    ):
        out.damage.append(
            Damage(
                "data",
                "the data section's CRC does not match: a byte outside the chunks' data is "
                "damaged (a record header, a metadata record or a message index); every "
                "chunk read passed its own CRC",
            )
        )
    if out.summary is None and not any(d.kind == "summary" for d in out.damage):
        out.damage.append(
            Damage(
                "truncated",
                "the summary section at the end of the file is truncated (all recorded "
                "data is intact)",
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
