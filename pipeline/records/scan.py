"""What survives of an MCAP record file, read through the mcap package.

* A file whose footer and summary section are intact (the summary's CRC checked) is read with mcap's
  seeking reader: messages through the chunk index (only chunks overlapping a requested time range
  are read; every chunk's CRC checked), metadata through the metadata index, and, on a full read,
  the data section's CRC from the data-end record (the writer enables it), so a flipped byte
  anywhere is noticed. If any of that fails, the file is read as below, with its summary's index.
* Otherwise (a killed run, a cut copy, damage) it is read front to back with mcap's
  ``StreamReader(emit_chunks=True)``, every chunk through ``breakup_chunk(validate_crc=True)``. A
  chunk that fails is a :class:`Damage` and reading goes on; the message index records after it
  say what it held. A record whose header is wrong stops the stream reader; a new one starts at the
  next record the summary's indexes name or, without them, at the next offset where a valid chunk
  (its CRC checked), metadata or data-end record starts. A record running past the end of a file
  no valid record follows is a truncation.

Channel definitions lost with a damaged part come from a later copy or, for this writer's files,
from its fixed channel layout (:data:`WRITER_CHANNELS`). A file with nothing to read (empty, not
MCAP) raises :class:`RecordsError`, naming the file and the problem.
"""
from __future__ import annotations

import io
import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (Attachment, Channel, Chunk, DataEnd, Footer, Header, Message, MessageIndex, Metadata,
                          Schema)
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.summary import Summary

from pipeline.errors import UserError

from . import schema as S

MAGIC = b"\x89MCAP0\r\n"
#: The header's library string of files written by :class:`pipeline.records.RecordWriter`.
LIBRARY = "pipeline.records/" + S.FORMAT_VERSION
#: The writer registers these first, in this order, in every file (tested): channel id -> (topic,
#: schema id, message class); used when every copy of a file's channel definitions is lost.
WRITER_CHANNELS = {1: (S.TOPIC_EPISODES, 1, S.EpisodeBatch), 2: (S.TOPIC_SUBSTITUTIONS, 2, S.Substitution)}
_OPCODE = {Header: Opcode.HEADER, Schema: Opcode.SCHEMA, Channel: Opcode.CHANNEL, Message: Opcode.MESSAGE,
           Chunk: Opcode.CHUNK, MessageIndex: Opcode.MESSAGE_INDEX, Metadata: Opcode.METADATA,
           Attachment: Opcode.ATTACHMENT, DataEnd: Opcode.DATA_END}
_RESYNC = re.compile(rb"[\x06\x0c\x0f]")  # chunk, metadata, data end: where reading can start again
_HEAD = struct.Struct("<BQ")
_FOOTER_SIZE = 1 + 8 + 8 + 8 + 4
_SIGNATURES = ((b"\x89PNG\r\n\x1a\n", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"),
               (b"PK\x03\x04", "a zip archive"), (b"\x1f\x8b", "a gzip file"), (b"\x28\xb5\x2f\xfd", "a zstd file"),
               (b"SQLite format 3\x00", "an SQLite database"), (b"RRF", "a Rerun .rrd file"))


class RecordsError(UserError):
    """A record file that cannot be read at all; the message names the file and the problem."""


@dataclass
class Damage:
    """One damaged or missing part of a file."""

    kind: str  # "chunk", "bytes", "metadata", "summary", "decode", "data" (damage); "truncated" (ends early)
    what: str  # a sentence naming the part, where it is and what is wrong with it
    span: tuple[int, int] | None = None  # log times of the messages it held, when known
    index: dict[int, list[int]] = field(default_factory=dict)  # a lost chunk's message index: channel -> times
    held: dict[str, int] = field(default_factory=dict)  # message kind -> count (from ``index``)
    batch_stamps: list[int] = field(default_factory=list)  # log times of its episode batches
    lost: list = field(default_factory=list)  # (run, first, last) episode ranges, filled by the loss accounting


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
    orphans: list[Message] = field(default_factory=list)


def message_kind(topic: str) -> str | None:
    """How a lost message is counted: episode batches, substitutions, pictures, support pictures."""
    return {S.TOPIC_EPISODES: "episode batches", S.TOPIC_SUBSTITUTIONS: "substitutions"}.get(topic) or (
        "pictures" if topic.startswith(S.TOPIC_PICTURES + "/") else
        "support pictures" if topic.startswith(S.TOPIC_SUPPORT + "/") else None)


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
        raise RecordsError(_not_mcap(path, data))
    out = Scan(path)
    summary = out.summary = _summary(data, out)
    if summary is not None:
        try:
            _read_indexed(data, out, summary, time_range)
            out.complete = not out.damage
            return out
        except Exception:  # a damaged chunk or record: read it record by record
            out = Scan(path, schemas=dict(summary.schemas), channels=dict(summary.channels), summary=summary)
    _walk(data, out, time_range)
    _resolve_orphans(out, time_range)
    for d in out.damage:
        for cid, times in d.index.items():
            topic = out.channels[cid].topic if cid in out.channels else None
            kind = message_kind(topic) if topic else ("pictures" if out.library == LIBRARY and cid > 2 else
                                                      "messages of channels whose definitions were lost")
            if topic == S.TOPIC_EPISODES:
                d.batch_stamps = sorted(times)
            if kind:
                d.held[kind] = d.held.get(kind, 0) + len(times)
    return out


def _not_mcap(path: Path, data: bytes) -> str:
    if not data:
        return f"{path}: empty file (0 bytes): not an MCAP record file"
    if len(data) < 8 and MAGIC.startswith(data):
        return f"{path}: truncated after {len(data)} bytes, inside the MCAP magic bytes: nothing to read"
    what = next((w for sig, w in _SIGNATURES if data.startswith(sig)), None)
    return f"{path}: not an MCAP file ({f'it is {what}' if what else 'it does not start with the MCAP magic bytes'})"


def _summary(data: bytes, out: Scan) -> Summary | None:
    """The summary section, if the footer is intact and the section's CRC matches."""
    foot = len(data) - 8 - _FOOTER_SIZE
    if foot < 8 or data[-8:] != MAGIC:
        return None
    try:
        footer = next(StreamReader(io.BytesIO(data[foot:]), skip_magic=True).records)
        if not isinstance(footer, Footer) or _HEAD.unpack_from(data, foot)[1] != _FOOTER_SIZE - 9:
            raise ValueError("not a footer")
    except Exception:
        out.damage.append(Damage("summary", f"the footer at byte {foot} is damaged; the file was read without its "
                                            "summary section"))
        return None
    start = footer.summary_start
    if start == 0:
        return None
    problem = "names a summary section outside the file" if not 8 < start <= foot else None
    if problem is None and footer.summary_crc and zlib.crc32(data[start:foot + _FOOTER_SIZE - 4]) != footer.summary_crc:
        problem = "CRC mismatch"
    try:
        summary = None if problem else make_reader(io.BytesIO(data)).get_summary()
    except Exception as e:
        problem = f"it does not parse ({type(e).__name__}: {e})"
    if problem:
        out.damage.append(Damage("summary", f"the summary section at byte {start} is damaged ({problem}); the file "
                                            "was read without it"))
        return None
    summary.chunk_indexes.sort(key=lambda c: c.chunk_start_offset)
    summary.data_end = start
    return summary


def _read_indexed(data: bytes, out: Scan, summary: Summary, time_range) -> None:
    """A file with an intact summary, through mcap's seeking reader; raises on any damage found."""
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    out.library = reader.get_header().library
    out.schemas, out.channels = dict(summary.schemas), dict(summary.channels)
    for m in reader.iter_metadata():
        out.metadata[m.name] = dict(m.metadata)
    queries: list[dict] = [{}]
    if time_range is not None:  # pictures (stamped 0) always, the rest in the range
        pictures = {c.topic for c in summary.channels.values() if c.topic.startswith((S.TOPIC_PICTURES, S.TOPIC_SUPPORT))}
        queries = [dict(topics=sorted(pictures)), dict(topics=sorted({c.topic for c in summary.channels.values()}
                                                                     - pictures),
                                                       starting_at=time_range[0], ending_before=time_range[1])]
    for query in queries:
        for _, ch, m in reader.iter_messages(log_time_order=False, **query):
            out.messages.setdefault(ch.topic, []).append((m.log_time, m.data))
    end = summary.data_end - 13  # the data-end record
    rec = next(StreamReader(io.BytesIO(data[end:summary.data_end]), skip_magic=True).records)
    if not isinstance(rec, DataEnd):
        raise ValueError("no data-end record before the summary")
    _data_end(data, out, rec, end, time_range)


def _walk(data: bytes, out: Scan, time_range) -> None:
    """Front to back with mcap's stream reader, a new one after each damaged record."""
    n, summary = len(data), out.summary
    limit = summary.data_end if summary is not None else n
    indexed = {c.chunk_start_offset: (k, c) for k, c in enumerate(summary.chunk_indexes, 1)} if summary else {}
    of = f" of {len(indexed)}" if summary is not None else ""
    chunks, lost, visited = 0, None, set()
    f, pos = io.BytesIO(data), 8

    def damaged_chunk(start: int, why: str, span) -> Damage:
        k = indexed[start][0] if start in indexed else chunks
        out.damage.append(Damage("chunk", f"chunk {k}{of} damaged ({why}) at byte {start}", span))
        visited.add(start)
        return out.damage[-1]

    while pos is not None and pos < limit:
        f.seek(start := pos)
        pos = None
        try:
            for rec in StreamReader(f, skip_magic=True, emit_chunks=True, record_size_limit=n).records:
                end = f.tell()
                if data[start] != _OPCODE.get(type(rec)) or (start in indexed and end - start != indexed[start][1]
                                                              .chunk_length):
                    raise ValueError("its record header disagrees with " + ("the chunk index" if start in indexed
                                                                            else "its contents"))
                if isinstance(rec, MessageIndex):
                    if lost is not None:  # what the damaged chunk before it held
                        lost.index.setdefault(rec.channel_id, []).extend(t for t, _ in rec.records)
                    start = end
                    continue
                lost = None
                if isinstance(rec, Chunk):
                    if end - start != _chunk_size(rec):
                        raise ValueError("bad chunk header: its data length disagrees with its record length")
                    chunks += 1
                    visited.add(start)
                    why = _take_chunk(out, rec, time_range)
                    if why:
                        lost = damaged_chunk(start, why, (rec.message_start_time, rec.message_end_time))
                elif isinstance(rec, DataEnd):
                    _data_end(data, out, rec, start, time_range)
                    break
                elif isinstance(rec, Metadata):
                    out.metadata[rec.name] = dict(rec.metadata)
                elif isinstance(rec, Header):
                    out.library = rec.library
                else:
                    _take(out, rec, time_range)
                start = end
        except Exception as e:
            why = str(e) if isinstance(e, ValueError) and str(e) else f"{type(e).__name__}: {e}".rstrip(": ")
            if start >= n:
                out.damage.append(Damage("truncated", f"the file is truncated: it ends after {n} bytes at a record "
                                                      "boundary, before its data-end record; anything written after "
                                                      "that and the summary section are lost"))
            elif start in indexed:  # the chunk index says where the next record starts
                lost = damaged_chunk(start, why, (indexed[start][1].message_start_time,
                                                  indexed[start][1].message_end_time))
                pos = start + indexed[start][1].chunk_length
            else:
                opcode, length = _HEAD.unpack_from(data, start) if start + 9 <= n else (data[start], n)
                span = struct.unpack_from("<QQ", data, start + 9) if opcode == Opcode.CHUNK and start + 25 <= n else None
                span = span if span and span[0] <= span[1] else None
                pos = _find_next(data, start + 1, limit)
                if pos is None and start + 9 + length > n:
                    name = f"chunk {chunks + 1}, of {length} bytes at byte {start}" + (
                        f", holding messages stamped {_describe_span(*span)}" if span else "") \
                        if opcode == Opcode.CHUNK else _record_name(opcode)
                    out.damage.append(Damage("truncated", f"the file is truncated: it ends {n - start - 9} bytes into "
                                                          f"{name}; that record, anything after it and the summary "
                                                          "section are lost", span))
                elif opcode == Opcode.CHUNK:
                    chunks += 1
                    lost = damaged_chunk(start, why, span)
                    lost.what += f"; reading went on at byte {pos}" if pos else ""
                else:
                    out.damage.append(Damage("bytes", f"a damaged record ({why}) at byte {start} was skipped"
                                                      + (f"; reading went on at byte {pos}" if pos else "")))
    for k, c in indexed.values():
        if c.chunk_start_offset not in visited:
            out.damage.append(Damage("chunk", f"chunk {k}{of} at byte {c.chunk_start_offset} was not reached (the "
                                              "records before it are damaged)",
                                     (c.message_start_time, c.message_end_time)))


def _take_chunk(out: Scan, rec: Chunk, time_range) -> str | None:
    """File the records of a chunk (left unread outside ``time_range``); why it is damaged, or None."""
    if time_range is not None and out.channels and rec.message_start_time != 0 and (
            rec.message_end_time < time_range[0] or rec.message_start_time >= time_range[1]):
        return None
    try:
        records = breakup_chunk(rec, validate_crc=True)
    except CRCValidationError:
        return "CRC mismatch"
    except Exception as e:
        if type(e).__module__.startswith(("zstandard", "lz4")) or isinstance(e, RuntimeError):
            return f"bad decompression ({type(e).__name__}: {e})"
        return "bad record lengths"
    for r in records:
        _take(out, r, time_range)
    return None


def _data_end(data: bytes, out: Scan, rec: DataEnd, start: int, time_range) -> None:
    """The data section's CRC (on a full read of a file with no other damage), and a lost summary."""
    if rec.data_section_crc and time_range is None and not out.damage and zlib.crc32(data[:start]) != rec.data_section_crc:
        out.damage.append(Damage("data", "the data section's CRC does not match: a byte outside the chunks' data is "
                                         "damaged (a record header, a metadata record or a message index); every "
                                         "chunk read passed its own CRC"))
    if out.summary is None and not any(d.kind == "summary" for d in out.damage):
        out.damage.append(Damage("truncated", "the summary section at the end of the file is truncated (all recorded "
                                              "data is intact)"))


def _chunk_size(rec: Chunk) -> int:
    """The bytes a chunk record takes: its header, then its fields (times, sizes, CRC, compression, data)."""
    return 9 + 8 * 3 + 4 + 4 + len(rec.compression) + 8 + len(rec.data)


def _record_name(opcode: int) -> str:
    try:
        return f"a {Opcode(opcode).name.lower().replace('_', ' ')} record"
    except ValueError:
        return f"a record (opcode {opcode:#x})"


def _describe_span(start: int, end: int) -> str:
    (r0, e0, _), (r1, e1, _) = S.split_log_time(start), S.split_log_time(end)
    return f"run {r0} episode {e0}" + ("" if (r0, e0) == (r1, e1) else f" to run {r1} episode {e1}")


def _find_next(data: bytes, start: int, limit: int) -> int | None:
    """The first offset >= ``start`` where a valid chunk (CRC checked), metadata or data-end record starts."""
    for m in _RESYNC.finditer(data, start, limit):
        p = m.start()
        try:
            opcode, length = _HEAD.unpack_from(data, p)
            if p + 9 + length > limit:
                continue
            rec = next(StreamReader(io.BytesIO(data[p:p + 9 + length]), skip_magic=True, emit_chunks=True).records)
            if isinstance(rec, Chunk) and rec.uncompressed_crc and _chunk_size(rec) == 9 + length:
                breakup_chunk(rec, validate_crc=True)
                return p
            if isinstance(rec, Metadata) or (isinstance(rec, DataEnd) and length == 4):
                return p
        except Exception:
            continue
    return None


def _take(out: Scan, rec, time_range) -> None:
    """File a schema, channel, message or attachment record (a message of an unknown channel waits)."""
    if isinstance(rec, Message):
        ch = out.channels.get(rec.channel_id)
        if ch is None:
            out.orphans.append(rec)
        elif time_range is None or time_range[0] <= rec.log_time < time_range[1] \
                or ch.topic.startswith((S.TOPIC_PICTURES, S.TOPIC_SUPPORT)):
            out.messages.setdefault(ch.topic, []).append((rec.log_time, rec.data))
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec


def _resolve_orphans(out: Scan, time_range) -> None:
    """Messages read before (or without) their channel's definition: a later definition, or this
    writer's fixed layout for its own files; the rest are dropped, and counted."""
    missing = {m.channel_id for m in out.orphans} - set(out.channels)
    used = []
    for cid in sorted(missing & set(WRITER_CHANNELS)) if out.library == LIBRARY else ():
        topic, sid, cls = WRITER_CHANNELS[cid]
        out.channels[cid] = Channel(id=cid, topic=topic, message_encoding="protobuf", schema_id=sid, metadata={})
        out.schemas.setdefault(sid, Schema(id=sid, name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                                           data=S.file_descriptor_set(cls)))
        used.append(topic)
    if used:
        out.notes.append(f"the definitions of channels {', '.join(used)} were lost with the damaged part; taken "
                         f"from this writer's fixed channel layout ({LIBRARY})")
    orphans, out.orphans = out.orphans, []
    for m in orphans:
        if m.channel_id in out.channels:
            _take(out, m, time_range)
        else:
            out.dropped += 1
