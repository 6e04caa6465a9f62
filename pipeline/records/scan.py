"""Front-to-back MCAP scanning that survives truncated and damaged files.

The mcap package's seeking reader raises on a file without a valid summary (a killed run), and its
stream reader stops at the first bad record. This scanner walks the length-prefixed records itself,
so a damaged spot loses only what it held and the scan says exactly what that was:

* channel and schema definitions are taken from wherever a copy survives: the summary section
  (checked against its CRC) before anything else, then the chunks; a message whose channel was
  defined only in a lost chunk is resolved at the end, from a later definition or, for a file of
  this writer (its header names ``pipeline.records/<format>``), from the writer's fixed channel
  layout (:data:`WRITER_CHANNELS`);
* a chunk whose CRC, compression or inner record lengths are wrong is skipped as damaged
  (:class:`Damage`, with the log-time span of its messages when its header or the chunk index
  still says it) and reading goes on with the next record;
* after a record whose header is wrong (a bad length, an unknown opcode) the scan resynchronises:
  to the next chunk or metadata record the summary's indexes name when the summary is intact,
  otherwise to the next offset where a valid chunk (its CRC checked), metadata or data-end record
  starts;
* a record that runs past the end of a file without a summary is a truncation (a killed run or a
  cut copy) when no valid record follows it.

Files that hold nothing to read (empty, too short, another format) raise :class:`RecordsError`
naming the file and the problem.
"""
from __future__ import annotations

import bisect
import re
import struct
import zlib
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, ChunkIndex, Message, MetadataIndex, Schema, Statistics

from pipeline.errors import UserError

from . import schema as S
from .schema import split_log_time

MAGIC = b"\x89MCAP0\r\n"
#: The header's library string of files written by :class:`pipeline.records.RecordWriter`.
LIBRARY = "pipeline.records/" + S.FORMAT_VERSION
#: The writer registers these schemas and channels first, in this order, in every file (tested):
#: channel id -> (topic, schema id, message class). Used only when every copy of a file's channel
#: definitions is lost (a killed run's file whose first chunk is damaged).
WRITER_CHANNELS = {1: (S.TOPIC_EPISODES, 1, S.EpisodeBatch), 2: (S.TOPIC_SUBSTITUTIONS, 2, S.Substitution)}

_RECORD_HEADER = struct.Struct("<BQ")
_CHUNK_FIXED = struct.Struct("<QQQII")  # start, end, uncompressed size, uncompressed crc, compression length
_CHUNK_TIMES = struct.Struct("<QQ")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, summary crc
_MESSAGE_HEADER = struct.Struct("<BQHIQQ")  # opcode, length, channel, sequence, log time, publish time
_DATA_OPCODES = frozenset({Opcode.HEADER, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.CHUNK,
                           Opcode.MESSAGE_INDEX, Opcode.ATTACHMENT, Opcode.METADATA, Opcode.DATA_END})
_RESYNC = re.compile(rb"[\x06\x0c\x0f]")  # chunk, metadata, data end: where reading can start again
_COMPRESSIONS = ("", "zstd", "lz4")
_SIGNATURES = ((b"\x89PNG\r\n\x1a\n", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"),
               (b"PK\x03\x04", "a zip archive"), (b"\x1f\x8b", "a gzip file"), (b"\x28\xb5\x2f\xfd", "a zstd file"),
               (b"SQLite format 3\x00", "an SQLite database"), (b"RRF", "a Rerun .rrd file"))


class RecordsError(UserError):
    """A record file that cannot be read at all (empty, not MCAP, another program's MCAP, nothing
    readable in it); the message names the file and the problem."""


@dataclass
class Damage:
    """One damaged or missing part of a file, found by :func:`scan`."""

    kind: str  # "chunk", "bytes", "metadata", "summary", "decode", "data" (damage); "truncated" (the file ends early)
    what: str  # a sentence naming the part, where it is and what is wrong with it
    offset: int
    span: tuple[int, int] | None = None  # log times of the messages it held, when known
    lost: list = field(default_factory=list)  # (run, first, last) episode ranges, filled by the reader
    # what a lost chunk held, from its message index records (written after it, outside it):
    index: dict[int, list[int]] = field(default_factory=dict)  # channel id -> log times
    batch_stamps: list[int] = field(default_factory=list)  # log times of its episode batches
    held: dict[str, int] = field(default_factory=dict)  # message kind -> count


@dataclass
class Summary:
    """What the summary section of a finished file holds (only when its CRC matches)."""

    data_end: int  # offset of the summary section: the data section ends there
    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    statistics: Statistics | None
    chunks: list[ChunkIndex]  # sorted by offset
    metadata: list[MetadataIndex]


@dataclass
class Scan:
    """What a scan of one file found. ``messages`` maps topic -> list of (log_time, data)."""

    path: Path
    size: int = 0
    library: str | None = None  # the Header record's library string
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: dict[str, list[tuple[int, bytes]]] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    damage: list[Damage] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # recovered, nothing lost (e.g. channels from the writer layout)
    summary: Summary | None = None
    complete: bool = False  # data end, intact summary and footer, and no damage found
    chunks_read: int = 0
    chunks_skipped: int = 0  # outside the requested time range, not lost
    chunks_damaged: int = 0
    dropped: int = 0  # messages whose channel definition is lost everywhere

    @property
    def problems(self) -> list[str]:
        return [d.what for d in self.damage]

    @property
    def n_chunks(self) -> int | None:
        """Chunks of the file by its index (None without an intact summary)."""
        return len(self.summary.chunks) if self.summary is not None else None


def describe_span(start: int, end: int) -> str:
    r0, e0, _ = split_log_time(start)
    r1, e1, _ = split_log_time(end)
    if (r0, e0) == (r1, e1):
        return f"run {r0} episode {e0}"
    return f"run {r0} episode {e0} to run {r1} episode {e1}"


# ------------------------------------------------------------------------------------ chunks
@dataclass
class _ChunkHead:
    start: int
    end: int
    uncompressed_size: int
    crc: int
    compression: str
    data_start: int
    data_len: int


def _chunk_head(data, body: int, length: int) -> _ChunkHead:
    """The chunk record's fields, checked against its record length (ValueError when they disagree)."""
    if length < _CHUNK_FIXED.size + 8:
        raise ValueError(f"its record length {length} is too short for a chunk")
    start, end, usize, crc, clen = _CHUNK_FIXED.unpack_from(data, body)
    p = body + _CHUNK_FIXED.size
    if clen > 16 or p + clen + 8 > body + length:
        raise ValueError(f"bad compression name length {clen}")
    comp = bytes(data[p:p + clen]).decode("ascii", errors="replace")
    if comp not in _COMPRESSIONS:
        raise ValueError(f"unknown compression {comp!r}")
    p += clen
    (dlen,) = _U64.unpack_from(data, p)
    p += 8
    if p + dlen != body + length:
        raise ValueError("its data length disagrees with its record length")
    if start > end:
        raise ValueError("its message start time is after its end time")
    return _ChunkHead(start, end, usize, crc, comp, p, dlen)


def _decompress(data, head: _ChunkHead, validate_crc: bool) -> bytes:
    raw = data[head.data_start:head.data_start + head.data_len]
    try:
        if head.compression == "zstd":
            import zstandard

            size = zstandard.frame_content_size(raw)
            if size not in (-1, head.uncompressed_size):
                raise ValueError(f"bad decompression: the zstd frame holds {size} bytes, the chunk says "
                                 f"{head.uncompressed_size}")
            out = zstandard.decompress(raw, head.uncompressed_size)
        elif head.compression == "lz4":
            import lz4.frame

            out = lz4.frame.decompress(bytes(raw))
        else:
            out = bytes(raw)
    except ValueError:
        raise
    except Exception as e:  # zstandard.ZstdError, lz4's RuntimeError: broken compressed data
        raise ValueError(f"bad decompression ({type(e).__name__}: {e})") from None
    if len(out) != head.uncompressed_size:
        raise ValueError(f"bad decompression: {len(out)} bytes, the chunk says {head.uncompressed_size}")
    if validate_crc and head.crc and zlib.crc32(out) != head.crc:
        raise ValueError("CRC mismatch")
    return out


def _inner_records(data: bytes) -> list:
    """The schema, channel and message records of a decompressed chunk (messages parsed with one
    struct call each: the mcap package's ``breakup_chunk`` reads them field by field, several times
    slower)."""
    out: list = []
    pos, n = 0, len(data)
    unpack_message = _MESSAGE_HEADER.unpack_from
    while pos < n:
        if pos + 9 > n:
            raise ValueError(f"bad record lengths: a record header inside the chunk is cut (at chunk byte {pos})")
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + 9 + length
        if end > n:
            raise ValueError(f"bad record lengths: a record inside the chunk runs past its end (at chunk byte {pos})")
        if opcode == Opcode.MESSAGE:
            if length < 22:
                raise ValueError(f"bad record lengths: a message record of {length} bytes (at chunk byte {pos})")
            _, _, channel, sequence, log_time, publish_time = unpack_message(data, pos)
            out.append(Message(channel_id=channel, sequence=sequence, log_time=log_time,
                               publish_time=publish_time, data=data[pos + 31:end]))
        elif opcode == Opcode.CHANNEL:
            out.append(Channel.read(ReadDataStream(BytesIO(data[pos + 9:end]))))
        elif opcode == Opcode.SCHEMA:
            out.append(Schema.read(ReadDataStream(BytesIO(data[pos + 9:end]))))
        pos = end
    return out


def chunk_records(chunk: Chunk, validate_crc: bool = True) -> list:
    """The schema, channel and message records of one chunk (an mcap ``Chunk`` record)."""
    head = _ChunkHead(chunk.message_start_time, chunk.message_end_time, chunk.uncompressed_size,
                      chunk.uncompressed_crc, chunk.compression, 0, len(chunk.data))
    return _inner_records(_decompress(memoryview(chunk.data), head, validate_crc))


# ------------------------------------------------------------------------------------ other records
def _string(data, p: int, end: int) -> tuple[str, int]:
    if p + 4 > end:
        raise ValueError("a string runs past its record")
    (k,) = _U32.unpack_from(data, p)
    if p + 4 + k > end:
        raise ValueError("a string runs past its record")
    return bytes(data[p + 4:p + 4 + k]).decode("utf-8"), p + 4 + k


def _metadata(data, body: int, length: int) -> tuple[str, dict[str, str]]:
    """A metadata record's name and key-value map; ValueError unless its lengths add up exactly."""
    end = body + length
    name, p = _string(data, body, end)
    if p + 4 > end:
        raise ValueError("its map runs past the record")
    (size,) = _U32.unpack_from(data, p)
    p += 4
    if p + size != end:
        raise ValueError("its map length disagrees with its record length")
    out = {}
    while p < end:
        k, p = _string(data, p, end)
        v, p = _string(data, p, end)
        out[k] = v
    if not name or not name.isprintable():
        raise ValueError(f"unreadable name {name!r}")
    return name, out


def _plausible(data, pos: int, limit: int) -> bool:
    """A record header at ``pos`` with a known opcode whose record ends by ``limit`` (or ``pos`` is
    ``limit``: the data section ends there)."""
    if pos == limit:
        return True
    if pos + 9 > limit:
        return False
    opcode, length = _RECORD_HEADER.unpack_from(data, pos)
    return opcode in _DATA_OPCODES and pos + 9 + length <= limit


def _read_summary(data, out: Scan) -> Summary | None:
    """The summary section named by the footer, if the file ends with an intact footer and magic
    and the summary's CRC matches; otherwise None (and a note of the damage when there is one)."""
    n = len(data)
    foot = n - 8 - _FOOTER.size
    if foot < 8 or bytes(data[n - 8:]) != MAGIC:
        return None
    opcode, length, start, offsets_start, crc = _FOOTER.unpack_from(data, foot)
    if opcode != Opcode.FOOTER or length != 20:
        out.damage.append(Damage("summary", f"the footer at byte {foot} is damaged; the file was read "
                                            "without its summary section", foot))
        return None
    if start == 0:
        start = foot
    if not 8 < start <= foot or (offsets_start and not start <= offsets_start <= foot):
        out.damage.append(Damage("summary", f"the footer at byte {foot} names a summary section outside the "
                                            "file; the file was read without it", foot))
        return None
    if crc:
        got = zlib.crc32(data[start:foot])
        got = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, start if start != foot else 0, offsets_start), got)
        if got != crc:
            out.damage.append(Damage("summary", f"the summary section at byte {start} is damaged (CRC mismatch); "
                                                "the file was read without it", start))
            return None
    summ = Summary(data_end=start, schemas={}, channels={}, statistics=None, chunks=[], metadata=[])
    pos = start
    try:
        while pos < foot:
            opcode, length = _RECORD_HEADER.unpack_from(data, pos)
            end = pos + 9 + length
            if end > foot:
                raise ValueError(f"a summary record at byte {pos} runs past the footer")
            body = ReadDataStream(BytesIO(data[pos + 9:end]))
            if opcode == Opcode.SCHEMA:
                s = Schema.read(body)
                summ.schemas[s.id] = s
            elif opcode == Opcode.CHANNEL:
                c = Channel.read(body)
                summ.channels[c.id] = c
            elif opcode == Opcode.STATISTICS:
                summ.statistics = Statistics.read(body)
            elif opcode == Opcode.CHUNK_INDEX:
                summ.chunks.append(ChunkIndex.read(body))
            elif opcode == Opcode.METADATA_INDEX:
                summ.metadata.append(MetadataIndex.read(body))
            pos = end
    except Exception as e:  # a summary with a matching (or no) CRC that does not parse
        out.damage.append(Damage("summary", f"the summary section at byte {start} does not parse "
                                            f"({type(e).__name__}: {e}); the file was read without it", start))
        return None
    summ.chunks.sort(key=lambda c: c.chunk_start_offset)
    return summ


def _record_name(opcode: int) -> str:
    try:
        return f"a {Opcode(opcode).name.lower().replace('_', ' ')} record"
    except ValueError:
        return f"a record (opcode {opcode:#x})"


def _not_mcap(path: Path, data: bytes) -> str:
    n = len(data)
    if n == 0:
        return f"{path}: empty file (0 bytes): not an MCAP record file"
    if n < len(MAGIC) and MAGIC.startswith(data):
        return f"{path}: truncated after {n} bytes, inside the MCAP magic bytes: nothing to read"
    for sig, what in _SIGNATURES:
        if data.startswith(sig):
            return f"{path}: not an MCAP file (it is {what})"
    return f"{path}: not an MCAP file (it does not start with the MCAP magic bytes)"


# ------------------------------------------------------------------------------------ the scan
def scan(path: str | Path, *, time_range: tuple[int, int] | None = None, validate_crcs: bool = True) -> Scan:
    """Read every intact record of ``path``. ``time_range`` (inclusive start, exclusive end, ns)
    skips chunks and messages outside it without decompressing them (pictures are always read)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except IsADirectoryError:
        raise RecordsError(f"{path}: is a folder, not a record file") from None
    except OSError as e:
        raise RecordsError(f"{path}: cannot be read ({e.strerror or e})") from None
    if raw[:8] != MAGIC:
        raise RecordsError(_not_mcap(path, raw))
    data = memoryview(raw)
    n = len(data)
    out = Scan(path=path, size=n)
    summ = out.summary = _read_summary(data, out)
    if summ is not None:
        out.schemas.update(summ.schemas)
        out.channels.update(summ.channels)
        limit = summ.data_end
        chunk_at = {ci.chunk_start_offset: (k, ci) for k, ci in enumerate(summ.chunks, 1)}
        meta_at = {mi.offset: mi for mi in summ.metadata}
        anchors = sorted(set(chunk_at) | set(meta_at) | {limit - 13})  # 13: the data-end record
    else:
        limit, chunk_at, meta_at, anchors = n, {}, {}, []
    n_chunks = len(chunk_at) if summ is not None else None
    visited: set[int] = set()
    orphans: list[Message] = []  # messages whose channel is not known (yet)
    validated: dict[int, list] = {}  # records of chunks already decoded while resynchronising
    chunk_no = 0
    data_end_seen = False
    lost_chunk: Damage | None = None  # the damaged chunk whose message index records may follow

    def chunk_name(k: int) -> str:
        return f"chunk {k} of {n_chunks}" if n_chunks is not None else f"chunk {k}"

    def resync(pos: int) -> int | None:
        """Where reading can go on after damage at ``pos``."""
        if anchors:
            i = bisect.bisect_right(anchors, pos)
            return anchors[i] if i < len(anchors) else None
        return _find_next(data, pos + 1, limit, validate_crcs, validated)

    def skip_bytes(pos: int, reason: str, span=None, chunk: str | None = None) -> int | None:
        nxt = resync(pos)
        stop = nxt if nxt is not None else limit
        tail = (f"reading went on at byte {nxt}" if nxt is not None
                else "no intact record follows, so the rest of the file is lost")
        if chunk is not None:
            out.chunks_damaged += 1
            held = f", holding messages stamped {describe_span(*span)}" if span else ""
            out.damage.append(Damage("chunk", f"{chunk} damaged ({reason}) at byte {pos}{held}; bytes {pos}-{stop} "
                                              f"were skipped and {tail}", pos, span))
        else:
            held = f" (they held messages stamped {describe_span(*span)})" if span else ""
            out.damage.append(Damage("bytes", f"damaged bytes at {pos}-{stop} ({reason}){held} were skipped; "
                                              f"{tail}", pos, span))
        return nxt

    pos = 8
    while pos < limit:
        if pos + 9 > limit:
            if summ is None:
                out.damage.append(Damage("truncated", f"the file is truncated: it ends {n - pos} bytes into a "
                                                      f"record header at byte {pos}; the summary section is lost", pos))
            else:
                out.damage.append(Damage("bytes", f"damaged bytes at {pos}-{limit} before the summary were skipped", pos))
            break
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        body = pos + 9
        end = body + length
        if opcode == Opcode.MESSAGE_INDEX and lost_chunk is not None and end <= limit and (
                not anchors or end <= anchors[min(bisect.bisect_right(anchors, pos), len(anchors) - 1)]
                or anchors[-1] <= pos):
            _message_index(data, body, length, lost_chunk)  # what the damaged chunk before it held
            pos = end
            continue
        lost_chunk = None
        if pos in chunk_at:  # the chunk index says a chunk of this length starts here
            k, ci = chunk_at[pos]
            chunk_no = k
            if opcode != Opcode.CHUNK or 9 + length != ci.chunk_length:
                visited.add(pos)
                out.chunks_damaged += 1
                out.damage.append(Damage("chunk", f"{chunk_name(k)} damaged (its record header disagrees with the "
                                                  f"chunk index) at byte {pos}", pos,
                                         (ci.message_start_time, ci.message_end_time)))
                lost_chunk = out.damage[-1]
                pos += ci.chunk_length
                continue
        elif pos in meta_at and (opcode != Opcode.METADATA or 9 + length != meta_at[pos].length):
            mi = meta_at[pos]
            out.damage.append(Damage("metadata", f"metadata record '{mi.name}' damaged (its record header disagrees "
                                                 f"with the metadata index) at byte {pos}", pos))
            pos += mi.length
            continue
        if opcode not in _DATA_OPCODES or end > limit:
            if summ is None and end > n and opcode in _DATA_OPCODES:
                nxt = _find_next(data, pos + 1, limit, validate_crcs, validated)
                if nxt is None:  # the file ends inside this record: truncated
                    what = f"{_record_name(opcode)} of {length} bytes at byte {pos}"
                    span = None
                    if opcode == Opcode.CHUNK and n - body >= 16:
                        span = _CHUNK_TIMES.unpack_from(data, body)
                        span = span if span[0] <= span[1] else None
                        what = f"{chunk_name(chunk_no + 1)}, of {length} bytes at byte {pos}" + (
                            f", holding messages stamped {describe_span(*span)}" if span else "")
                    out.damage.append(Damage("truncated", f"the file is truncated: it ends {n - body} bytes into "
                                                          f"{what}; that record, anything after it and the summary "
                                                          "section are lost", pos, span))
                    break
            reason = (f"bad record length {length}" if opcode in _DATA_OPCODES else f"invalid record opcode {opcode:#x}")
            span, chunk = None, None
            if opcode == Opcode.CHUNK and pos + 9 + 16 <= limit:
                chunk_no += 1
                chunk = chunk_name(chunk_no)
                span = _CHUNK_TIMES.unpack_from(data, body)
                span = span if span[0] <= span[1] else None
            nxt = skip_bytes(pos, reason, span, chunk)
            if nxt is None:
                break
            pos = nxt
            continue
        if anchors and end > anchors[min(bisect.bisect_right(anchors, pos), len(anchors) - 1)] > pos:
            nxt = skip_bytes(pos, f"a record of {length} bytes (opcode {opcode:#x}) runs over the next indexed record")
            if nxt is None:
                break
            pos = nxt
            continue
        if opcode == Opcode.CHUNK:
            if pos not in chunk_at:
                chunk_no += 1
            visited.add(pos)
            try:
                head = _chunk_head(data, body, length)
            except Exception as e:
                out.chunks_damaged += 1
                k = chunk_at[pos][0] if pos in chunk_at else chunk_no
                span = (chunk_at[pos][1].message_start_time, chunk_at[pos][1].message_end_time) if pos in chunk_at else None
                if span is None and length >= 16:
                    span = _CHUNK_TIMES.unpack_from(data, body)
                    span = span if span[0] <= span[1] else None
                nxt = end if pos in chunk_at or _plausible(data, end, limit) else resync(pos)
                out.damage.append(Damage("chunk", f"{chunk_name(k)} damaged (bad chunk header: {e}) at byte {pos}"
                                         + ("" if nxt == end else f"; reading went on at byte {nxt}"), pos, span))
                lost_chunk = out.damage[-1] if nxt == end else None
                if nxt is None:
                    break
                pos = nxt
                continue
            if time_range is not None and (head.end < time_range[0] or head.start >= time_range[1]) \
                    and out.channels and head.start != 0:
                # outside the range: skipped unread (pictures, stamped 0, are always read; channels
                # come from the summary or from the first chunk, which holds time 0 too)
                out.chunks_skipped += 1
                pos = end
                continue
            try:
                records = validated.pop(pos, None)
                if records is None:
                    records = _inner_records(_decompress(data, head, validate_crcs))
            except Exception as e:
                out.chunks_damaged += 1
                k = chunk_at[pos][0] if pos in chunk_at else chunk_no
                reason = str(e) if isinstance(e, ValueError) else f"{type(e).__name__}: {e}"
                nxt = end if pos in chunk_at or _plausible(data, end, limit) else resync(pos)
                out.damage.append(Damage("chunk", f"{chunk_name(k)} damaged ({reason}) at byte {pos}"
                                         + ("" if nxt == end else f"; reading went on at byte {nxt}"), pos,
                                         (head.start, head.end)))
                lost_chunk = out.damage[-1] if nxt == end else None
                if nxt is None:
                    break
                pos = nxt
                continue
            out.chunks_read += 1
            for rec in records:
                _take(out, rec, time_range, orphans)
        elif opcode == Opcode.METADATA:
            try:
                name, values = _metadata(data, body, length)
            except Exception as e:
                nxt = end if pos in meta_at or _plausible(data, end, limit) else resync(pos)
                name = f" '{meta_at[pos].name}'" if pos in meta_at else ""
                out.damage.append(Damage("metadata", f"metadata record{name} damaged ({e}) at byte {pos}", pos))
                if nxt is None:
                    break
                pos = nxt
                continue
            out.metadata[name] = values
        elif opcode == Opcode.HEADER:
            try:
                br = ReadDataStream(BytesIO(data[body:end]))
                br.read_prefixed_string()  # profile
                out.library = br.read_prefixed_string()
            except Exception:
                out.damage.append(Damage("metadata", f"the header record at byte {pos} is damaged", pos))
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.ATTACHMENT):
            try:
                rd = ReadDataStream(BytesIO(data[body:end]))
                rec = (Schema.read(rd) if opcode == Opcode.SCHEMA else Channel.read(rd) if opcode == Opcode.CHANNEL
                       else Message.read(rd, length) if opcode == Opcode.MESSAGE else Attachment.read(rd))
            except Exception as e:
                out.damage.append(Damage("bytes", f"a damaged record (opcode {opcode:#x}) at byte {pos} was skipped "
                                                  f"({type(e).__name__}: {e})", pos))
                pos = end
                continue
            _take(out, rec, time_range, orphans)
        elif opcode == Opcode.DATA_END:
            data_end_seen = True
            crc = _U32.unpack_from(data, body)[0] if length >= 4 else 0
            if crc and validate_crcs and time_range is None and not out.damage and zlib.crc32(data[:pos]) != crc:
                out.damage.append(Damage("data", "the data section's CRC does not match: a byte outside the chunks "
                                                 "is damaged (the header, a metadata record or a message index); "
                                                 "every chunk read passed its own CRC", pos))
            if summ is None and not any(d.kind == "summary" for d in out.damage):
                out.damage.append(Damage("truncated", "the summary section at the end of the file is truncated "
                                                      "(all recorded data is intact)", end))
            break
        pos = end
    else:
        if summ is None:
            out.damage.append(Damage("truncated", f"the file is truncated: it ends after {n} bytes at a record "
                                                  "boundary, before its data-end record; anything written after "
                                                  "that and the summary section are lost", n))
    for k, ci in enumerate(summ.chunks if summ is not None else (), 1):
        if ci.chunk_start_offset not in visited:
            out.chunks_damaged += 1
            out.damage.append(Damage("chunk", f"{chunk_name(k)} at byte {ci.chunk_start_offset} was not reached "
                                              "(the records before it are damaged)", ci.chunk_start_offset,
                                     (ci.message_start_time, ci.message_end_time)))
    _resolve_orphans(out, orphans, time_range)
    for d in out.damage:
        for cid, times in d.index.items():
            topic = out.channels[cid].topic if cid in out.channels else None
            kind = message_kind(topic) if topic else None
            if topic is None:  # defined only in the lost chunk; after the writer's two, its pictures
                kind = "pictures" if out.library == LIBRARY and cid > max(WRITER_CHANNELS) else \
                    "messages of channels whose definitions were lost"
            if topic == S.TOPIC_EPISODES:
                d.batch_stamps = sorted(times)
            if kind:
                d.held[kind] = d.held.get(kind, 0) + len(times)
    out.complete = data_end_seen and summ is not None and not out.damage
    return out


def message_kind(topic: str) -> str | None:
    """How a lost message is counted: episode batches, substitutions, pictures, support pictures."""
    if topic == S.TOPIC_EPISODES:
        return "episode batches"
    if topic == S.TOPIC_SUBSTITUTIONS:
        return "substitutions"
    if topic.startswith(S.TOPIC_PICTURES + "/"):
        return "pictures"
    if topic.startswith(S.TOPIC_SUPPORT + "/"):
        return "support pictures"
    return None


def _message_index(data, body: int, length: int, into: Damage) -> None:
    """The log times of a message index record (one channel of one chunk) into ``into.index``."""
    try:
        (cid,) = struct.unpack_from("<H", data, body)
        (size,) = _U32.unpack_from(data, body + 2)
        if size % 16 or 6 + size != length:
            return
        times = np.frombuffer(data, dtype="<u8", count=size // 8, offset=body + 6)[0::2]
        into.index.setdefault(cid, []).extend(int(t) for t in times)
    except Exception:  # a damaged index record: it only helps to say what was lost
        pass


def _find_next(data, start: int, limit: int, validate_crcs: bool, validated: dict[int, list]) -> int | None:
    """The first offset >= ``start`` where a valid chunk (its data decompresses to its CRC),
    metadata or data-end record starts; None if there is none before ``limit``."""
    for m in _RESYNC.finditer(data, start, limit):
        p = m.start()
        if p + 9 > limit:
            return None
        opcode, length = _RECORD_HEADER.unpack_from(data, p)
        end = p + 9 + length
        if end > limit:
            continue
        try:
            if opcode == Opcode.CHUNK:
                head = _chunk_head(data, p + 9, length)
                if not head.crc and validate_crcs:
                    continue  # without a CRC a chunk cannot be told from noise
                validated[p] = _inner_records(_decompress(data, head, True))
                return p
            if opcode == Opcode.METADATA:
                _metadata(data, p + 9, length)
                if _plausible(data, end, limit):
                    return p
            elif opcode == Opcode.DATA_END and length == 4:
                return p
        except Exception:
            continue
    return None


def _take(out: Scan, rec, time_range, orphans: list) -> None:
    """File one record (a message of an unknown channel waits in ``orphans``)."""
    if isinstance(rec, Message):
        ch = out.channels.get(rec.channel_id)
        if ch is None:
            orphans.append(rec)
            return
        if time_range is not None and not (time_range[0] <= rec.log_time < time_range[1]) \
                and not ch.topic.startswith(("/pictures", "/support")):
            return
        out.messages.setdefault(ch.topic, []).append((rec.log_time, rec.data))
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec
    elif isinstance(rec, Attachment):
        out.attachments[rec.name] = bytes(rec.data)


def _resolve_orphans(out: Scan, orphans: list[Message], time_range) -> None:
    """Messages read before (or without) their channel's definition: a later definition, or the
    writer's fixed layout for our own files; the rest are dropped, and counted."""
    if not orphans:
        return
    missing = {m.channel_id for m in orphans} - set(out.channels)
    if missing and out.library == LIBRARY:
        used = []
        for cid in sorted(missing & set(WRITER_CHANNELS)):
            topic, sid, cls = WRITER_CHANNELS[cid]
            out.channels[cid] = Channel(id=cid, topic=topic, message_encoding="protobuf", schema_id=sid, metadata={})
            out.schemas.setdefault(sid, Schema(id=sid, name=cls.DESCRIPTOR.full_name, encoding="protobuf",
                                               data=S.file_descriptor_set(cls)))
            used.append(topic)
        if used:
            out.notes.append(f"the definitions of channels {', '.join(used)} were lost with the damaged part; "
                             f"taken from this writer's fixed channel layout ({LIBRARY})")
    for m in orphans:
        ch = out.channels.get(m.channel_id)
        if ch is None:
            out.dropped += 1
            continue
        if time_range is not None and not (time_range[0] <= m.log_time < time_range[1]) \
                and not ch.topic.startswith(("/pictures", "/support")):
            continue
        out.messages.setdefault(ch.topic, []).append((m.log_time, m.data))
