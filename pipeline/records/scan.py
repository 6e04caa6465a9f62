"""Front-to-back MCAP scanning that survives truncated and corrupt files.

The mcap package's seeking reader raises on a file without a valid summary (a killed run), and its
stream reader stops at the first bad record. This scanner walks the length-prefixed records itself
(parsing each with the mcap package's record classes), so it can say exactly what was lost: it
keeps every complete chunk, skips a chunk whose CRC or compression is broken and goes on, and
stops at a record that runs past the end of the file, naming its offset and, for a chunk, the
(run, episode) range its messages covered.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path

import zlib

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, DataEnd, Message, Metadata, Schema

from .schema import split_log_time

MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = struct.Struct("<BQ")
_CHUNK_TIMES = struct.Struct("<QQ")
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log time, publish time


def _decompress(chunk: Chunk, validate_crc: bool) -> bytes:
    if chunk.compression == "zstd":
        import zstandard

        data = zstandard.decompress(chunk.data, chunk.uncompressed_size)
    elif chunk.compression == "lz4":
        import lz4.frame

        data = lz4.frame.decompress(chunk.data)
    elif chunk.compression == "":
        data = bytes(chunk.data)
    else:
        raise ValueError(f"unsupported chunk compression {chunk.compression!r}")
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f"chunk decompressed to {len(data)} bytes, expected {chunk.uncompressed_size}")
    if validate_crc and chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("chunk CRC mismatch")
    return data


def chunk_records(chunk: Chunk, validate_crc: bool = True) -> list:
    """The schema, channel and message records of one chunk (messages parsed with one struct call
    each: the mcap package's ``breakup_chunk`` reads them field by field, several times slower)."""
    data = _decompress(chunk, validate_crc)
    out: list = []
    pos, n = 0, len(data)
    unpack_message = _MESSAGE_HEADER.unpack_from
    while pos < n:
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + 9 + length
        if end > n:
            raise ValueError(f"a record inside the chunk runs past its end (at chunk byte {pos})")
        if opcode == Opcode.MESSAGE:
            _, _, channel, sequence, log_time, publish_time = unpack_message(data, pos)
            out.append(Message(channel_id=channel, sequence=sequence, log_time=log_time,
                               publish_time=publish_time, data=data[pos + 31:end]))
        elif opcode == Opcode.CHANNEL:
            out.append(Channel.read(ReadDataStream(BytesIO(data[pos + 9:end]))))
        elif opcode == Opcode.SCHEMA:
            out.append(Schema.read(ReadDataStream(BytesIO(data[pos + 9:end]))))
        pos = end
    return out


@dataclass
class Scan:
    """What a scan of one file found. ``messages`` maps topic -> list of (log_time, data)."""

    path: Path
    size: int = 0
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: dict[str, list[tuple[int, bytes]]] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)  # what was lost, one sentence each
    complete: bool = False  # the data section ended (DataEnd) and the file ends with the magic
    chunks_read: int = 0
    chunks_skipped: int = 0  # outside the requested time range, not lost


def _describe_span(start: int, end: int) -> str:
    r0, e0, _ = split_log_time(start)
    r1, e1, _ = split_log_time(end)
    return f"run {r0} episode {e0} to run {r1} episode {e1}"


def scan(path: str | Path, *, time_range: tuple[int, int] | None = None, validate_crcs: bool = True) -> Scan:
    """Read every complete record of ``path``. ``time_range`` (inclusive start, exclusive end, ns)
    skips chunks and messages outside it without decompressing them."""
    path = Path(path)
    data = memoryview(path.read_bytes())
    out = Scan(path=path, size=len(data))
    if len(data) < len(MAGIC) or bytes(data[:8]) != MAGIC:
        raise ValueError(f"{path}: not an MCAP file (missing the MCAP magic bytes at its start)")
    pending_unknown: int = 0
    ended = False  # a DataEnd, Footer or a problem stopped the scan
    pos = 8
    n = len(data)
    while pos < n:
        if pos + 9 > n:
            out.problems.append(f"the file is truncated: it ends {n - pos} bytes into a record header "
                                f"at byte {pos}; the summary section is lost")
            ended = True
            break
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        body_start = pos + 9
        end = body_start + length
        if end > n:
            what = f"a record (opcode {opcode:#x}) of {length} bytes at byte {pos}"
            if opcode == Opcode.CHUNK and n - body_start >= 16:
                start, stop = _CHUNK_TIMES.unpack_from(data, body_start)
                what = f"a chunk of {length} bytes at byte {pos} holding messages of {_describe_span(start, stop)}"
            out.problems.append(f"the file is truncated: it ends {n - body_start} bytes into {what}; "
                                "that record, anything after it and the summary section are lost")
            ended = True
            break
        body = ReadDataStream(BytesIO(data[body_start:end]))
        if opcode == Opcode.CHUNK:
            try:
                chunk = Chunk.read(body)
            except Exception as e:  # a corrupt chunk header
                out.problems.append(f"a corrupt chunk at byte {pos} was skipped ({type(e).__name__}: {e})")
                pos = end
                continue
            if time_range is not None and (chunk.message_end_time < time_range[0]
                                           or chunk.message_start_time >= time_range[1]):
                # Our writer defines every channel in the first chunk it writes, so once channels are
                # known a chunk outside the range is skipped unread (a message whose channel was
                # defined in a skipped chunk would be reported as dropped, never lost silently).
                if out.channels:
                    out.chunks_skipped += 1
                    pos = end
                    continue
            try:
                records = chunk_records(chunk, validate_crc=validate_crcs)
            except Exception as e:  # CRC mismatch, broken compression
                out.problems.append(
                    f"a corrupt chunk at byte {pos} with messages of "
                    f"{_describe_span(chunk.message_start_time, chunk.message_end_time)} was skipped "
                    f"({type(e).__name__}: {e})")
                pos = end
                continue
            out.chunks_read += 1
            for rec in records:
                pending_unknown += _take(out, rec, time_range)
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.METADATA, Opcode.ATTACHMENT):
            try:
                if opcode == Opcode.SCHEMA:
                    rec = Schema.read(body)
                elif opcode == Opcode.CHANNEL:
                    rec = Channel.read(body)
                elif opcode == Opcode.MESSAGE:
                    rec = Message.read(body, length)
                elif opcode == Opcode.METADATA:
                    rec = Metadata.read(body)
                else:
                    rec = Attachment.read(body)
            except Exception as e:
                out.problems.append(f"a corrupt record (opcode {opcode:#x}) at byte {pos} was skipped "
                                    f"({type(e).__name__}: {e})")
                pos = end
                continue
            pending_unknown += _take(out, rec, time_range)
        elif opcode == Opcode.DATA_END:
            DataEnd.read(body)
            out.complete = bytes(data[-8:]) == MAGIC and n - end >= 8
            if not out.complete:
                out.problems.append("the summary section at the end of the file is truncated "
                                    "(all recorded data is intact)")
            ended = True
            break
        elif opcode == Opcode.FOOTER:
            ended = True
            break
        elif opcode == 0:  # reserved opcode: zero-filled or overwritten bytes
            out.problems.append(f"invalid bytes (record opcode 0) at byte {pos}; reading stopped there, "
                                f"the remaining {n - pos} bytes are lost")
            ended = True
            break
        pos = end
    if not ended:
        out.problems.append(f"the file is truncated: it ends after {n} bytes at a record boundary, "
                            "before its data-end record; anything written after that and the summary "
                            "section are lost")
    if pending_unknown:
        out.problems.append(f"{pending_unknown} messages referred to channels defined in lost chunks and were dropped")
    return out


def _take(out: Scan, rec, time_range) -> int:
    """File one record; returns 1 if a message had to be dropped (unknown channel)."""
    if isinstance(rec, Message):
        ch = out.channels.get(rec.channel_id)
        if ch is None:
            return 1
        if time_range is not None and not (time_range[0] <= rec.log_time < time_range[1]) \
                and not ch.topic.startswith(("/pictures", "/support")):
            return 0
        out.messages.setdefault(ch.topic, []).append((rec.log_time, rec.data))
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec
    elif isinstance(rec, Metadata):
        out.metadata[rec.name] = dict(rec.metadata)
    elif isinstance(rec, Attachment):
        out.attachments[rec.name] = bytes(rec.data)
    return 0
