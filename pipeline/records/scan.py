"""What survives of an MCAP record file (docs/records.md "Damaged and truncated files"), read with
the mcap package's records. With an intact summary (its CRC checked): every chunk the chunk index
names, each CRC-checked, a damaged one skipped; then the data section's CRC. Without one: record by
record from the front, a damaged chunk skipped by its length, until the first record that cannot
be read. Each damaged or missing part is a :class:`Damage`; nothing readable raises
:class:`RecordsError`.
"""

from __future__ import annotations

import io
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Header, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import CRCValidationError, breakup_chunk
from mcap.summary import Summary

from pipeline.errors import UserError

from . import schema as S

MAGIC = b"\x89MCAP0\r\n"
#: The writer registers these first, in this order (tested): channel id -> (topic, schema id,
#: message class); used when every copy of a file's channel definitions is lost.
WRITER_CHANNELS = {1: (S.TOPIC_EPISODES, 1, S.EpisodeBatch)}
PICTURE_TOPICS = (S.TOPIC_PICTURES, S.TOPIC_SUPPORT)  # stamped 0: read whatever the time range
_HEAD, _FOOTER = struct.Struct("<BQ"), struct.Struct("<BQQQI")
_RECORDS = {  # what a data section of ours holds, by opcode
    Opcode.HEADER: Header,
    Opcode.SCHEMA: Schema,
    Opcode.CHANNEL: Channel,
    Opcode.CHUNK: Chunk,
    Opcode.MESSAGE_INDEX: MessageIndex,
    Opcode.METADATA: Metadata,
    Opcode.DATA_END: DataEnd,
}


class RecordsError(UserError):
    """A record file that cannot be read at all; the message names the file and the problem."""


@dataclass
class Damage:
    """One damaged or missing part of a file."""

    kind: str  # "chunk", "record", "stopped", "summary", "data", "metadata", "decode"; "truncated"
    what: str  # a sentence naming the part, where it is and what is wrong with it
    span: tuple[int, int] | None = None  # log times of the messages it held, when known


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
    dropped: int = 0  # messages whose channel definition is lost everywhere

    def add(self, kind: str, what: str, span: tuple[int, int] | None = None) -> None:
        self.damage.append(Damage(kind, what, span))


def scan(path: str | Path, *, time_range: tuple[int, int] | None = None) -> Scan:
    """Every intact record of ``path``; ``time_range`` (ns, end exclusive) leaves out the messages
    outside it, and with an intact summary their chunks unread (pictures are always read)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except IsADirectoryError:
        raise RecordsError(f"{path}: is a folder, not a record file") from None
    except OSError as e:
        raise RecordsError(f"{path}: cannot be read ({e.strerror or e})") from None
    if data[:8] != MAGIC:
        what = "empty file (0 bytes)" if not data else "not an MCAP file"
        raise RecordsError(f"{path}: {what}: it does not start with the MCAP magic bytes")
    out = Scan(path)
    data, appended = _closed(data)
    end = _summary(data, out)
    if out.summary is not None:
        _indexed(data, out, end, time_range)
    else:
        _stream(data, out, time_range)
    if appended:
        out.add(
            "data",
            f"{appended} bytes follow the file's closing magic bytes at byte {len(data) - 8} "
            "(added after its end): ignored, all recorded data is intact",
        )
    return out


def _closed(data: bytes) -> tuple[bytes, int]:
    """A whole file with bytes after its closing magic (appended to): the file up to that magic,
    and how many bytes follow it; else ``data`` and 0."""
    close = data.rfind(MAGIC) + 8
    if data[-8:] == MAGIC or close <= 16:
        return data, 0
    probe = Scan(Path())
    _summary(data[:close], probe)
    return (data[:close], len(data) - close) if probe.summary is not None else (data, 0)


def _summary(data: bytes, out: Scan) -> int:
    """The summary section as ``out.summary`` when intact (CRC checked); where the data ends."""
    foot = len(data) - 8 - _FOOTER.size
    if foot < 8 or data[-8:] != MAGIC:
        return len(data)
    opcode, length, start, _, crc = _FOOTER.unpack_from(data, foot)
    if (opcode, length) != (Opcode.FOOTER, _FOOTER.size - 9):
        problem = f"the footer at byte {foot} is damaged"
    elif not 8 < start <= foot:
        problem = f"the footer names a summary section outside the file ({start})"
    elif crc and zlib.crc32(data[start : foot + _FOOTER.size - 4]) != crc:
        problem = f"the summary section at byte {start} is damaged (CRC mismatch)"
    else:
        try:
            out.summary = make_reader(io.BytesIO(data)).get_summary()
            return start
        except Exception as e:
            problem = f"the summary section does not parse ({type(e).__name__}: {e})"
    out.add("summary", f"{problem}; the file was read without it")
    return len(data)


def _parse(data: bytes, pos: int, end: int):
    """The record from ``pos`` to ``end``; ValueError unless its kind is known and it fills them."""
    body = ReadDataStream(io.BytesIO(data[pos + 9 : end]))
    rec = _RECORDS[data[pos]].read(body)
    if body.count != end - pos - 9:
        raise ValueError("its record length disagrees with its contents")
    return rec


def _chunk(out: Scan, rec: Chunk, time_range) -> str | None:
    """File a chunk's records unless it lies outside ``time_range``; why it is damaged, or None."""
    t0, t1 = rec.message_start_time, rec.message_end_time
    if time_range is not None and t0 != 0 and (t1 < time_range[0] or t0 >= time_range[1]):
        return None
    try:
        records = breakup_chunk(rec, validate_crc=True)
    except CRCValidationError:
        return "CRC mismatch"
    except Exception as e:
        packed = type(e).__module__.startswith(("zstandard", "lz4"))
        return f"bad decompression ({type(e).__name__})" if packed else "bad record lengths"
    for r in records:
        _file(out, r, time_range)
    return None


def _file(out: Scan, rec, time_range) -> None:
    if isinstance(rec, Message):
        ch = out.channels.get(rec.channel_id) or _writer_channel(out, rec.channel_id)
        if ch is None:
            out.dropped += 1
        elif (
            time_range is None
            or time_range[0] <= rec.log_time < time_range[1]
            or ch.topic.startswith(PICTURE_TOPICS)
        ):
            out.messages.setdefault(ch.topic, []).append((rec.log_time, rec.data))
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec
    elif isinstance(rec, Metadata):
        out.metadata[rec.name] = dict(rec.metadata)
    elif isinstance(rec, Header):
        out.library = rec.library


def _writer_channel(out: Scan, cid: int) -> Channel | None:
    """Channel ``cid`` of this writer's fixed layout, for a file of ours whose definition is lost."""
    if out.library != S.LIBRARY or cid not in WRITER_CHANNELS:
        return None
    topic, sid, cls = WRITER_CHANNELS[cid]
    out.channels[cid] = Channel(cid, topic, "protobuf", {}, sid)
    schema = Schema(sid, S.file_descriptor_set(cls), "protobuf", cls.DESCRIPTOR.full_name)
    out.schemas.setdefault(sid, schema)
    out.notes.append(
        f"the definition of channel {topic} was lost with the damaged part; taken from this "
        f"writer's fixed channel layout ({S.LIBRARY})"
    )
    return out.channels[cid]


def _indexed(data: bytes, out: Scan, end: int, time_range) -> None:
    """A file with an intact summary: its header, metadata and indexed chunks, then its data end."""
    summary = out.summary
    out.schemas, out.channels = dict(summary.schemas), dict(summary.channels)
    where = [(8, "the header record")]
    where += [(m.offset, f"metadata record '{m.name}'") for m in summary.metadata_indexes]
    for pos, what in where:
        try:
            _file(out, _parse(data, pos, pos + 9 + _HEAD.unpack_from(data, pos)[1]), None)
        except Exception:
            out.add("metadata", f"{what} at byte {pos} is damaged")
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    for k, c in enumerate(chunks, 1):
        pos, span = c.chunk_start_offset, (c.message_start_time, c.message_end_time)
        try:  # the index says where the chunk ends: its record length is not needed
            why = _chunk(out, _parse(data, pos, pos + c.chunk_length), time_range)
        except Exception as e:
            why = f"bad chunk record ({type(e).__name__})"
        if why:
            what = f"chunk {k} of {len(chunks)} damaged ({why}) at byte {pos}"
            out.add("chunk", what, span)
    head, (crc,) = data[end - 13 : end - 4], struct.unpack_from("<I", data, end - 4)
    if head != _HEAD.pack(Opcode.DATA_END, 4):
        return out.add("data", "the data-end record before the summary is damaged")
    _data_crc(data, out, end - 13, crc, time_range)


def _data_crc(data: bytes, out: Scan, end: int, crc: int, time_range) -> None:
    """The data section's CRC, on a whole read that found no other damage."""
    if crc and time_range is None and not out.damage and zlib.crc32(memoryview(data)[:end]) != crc:
        what = "a byte outside the chunks' data is damaged (a record header, a metadata record or a message index)"
        out.add(
            "data",
            f"the data section's CRC does not match: {what}; every chunk read passed its own CRC",
        )


def _stream(data: bytes, out: Scan, time_range) -> None:
    """A file without an intact summary, record by record from the front."""
    n, pos, k = len(data), 8, 0
    while pos < n:
        if pos + 9 > n:
            return _truncated(out, f"it ends {n - pos} bytes into a record header at byte {pos}")
        opcode, length = _HEAD.unpack_from(data, pos)
        end = pos + 9 + length
        k += opcode == Opcode.CHUNK
        name = f"chunk {k}" if opcode == Opcode.CHUNK else _name(opcode)
        if end > n:
            return _truncated(out, f"it ends {n - pos - 9} bytes into {name} at byte {pos}")
        if opcode not in _RECORDS:
            out.add("record", f"{name} at byte {pos} is of no known kind: skipped")
            pos = end
            continue
        try:
            rec = _parse(data, pos, end)
        except Exception as e:
            why = str(e) if isinstance(e, ValueError) else type(e).__name__
            out.add("stopped", f"{name} at byte {pos} is damaged ({why}); reading stopped there")
            return
        if isinstance(rec, DataEnd):
            _data_crc(data, out, pos, rec.data_section_crc, time_range)
            if not any(d.kind == "summary" for d in out.damage):
                out.add(
                    "truncated",
                    "the summary section at the end of the file is truncated (all recorded data is intact)",
                )
            return
        why = (
            _chunk(out, rec, time_range) if isinstance(rec, Chunk) else _file(out, rec, time_range)
        )
        if why:
            span = (rec.message_start_time, rec.message_end_time)
            out.add("chunk", f"chunk {k} damaged ({why}) at byte {pos}", span)
        pos = end
    _truncated(out, f"it ends after {n} bytes at a record boundary, before its data-end record")


def _name(opcode: int) -> str:
    try:
        return f"a {Opcode(opcode).name.lower().replace('_', ' ')} record"
    except ValueError:
        return f"a record of opcode {opcode:#x}"


def _truncated(out: Scan, where: str) -> None:
    what = f"the file is truncated: {where}; that record, anything after it and the summary section are lost"
    out.add("truncated", what)
