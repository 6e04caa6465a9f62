"""What a scan of an MCAP record file found (:class:`Scan`, its :class:`Damage`), and how each
record read is filed into it: shared by the reader of intact files (``scan.py``) and the
front-to-back reader of damaged ones (``walk.py``).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, breakup_chunk
from mcap.summary import Summary

from pipeline.errors import UserError

from . import schema as S

#: The writer registers these first, in this order, in every file (tested): channel id -> (topic,
#: schema id, message class); used when every copy of a file's channel definitions is lost.
WRITER_CHANNELS = {1: (S.TOPIC_EPISODES, 1, S.EpisodeBatch)}
#: Topics stamped 0: read whatever the time range.
PICTURE_TOPICS = (S.TOPIC_PICTURES, S.TOPIC_SUPPORT)
#: A data-end record's opcode and length.
DATA_END_HEAD = struct.Struct("<BQ").pack(Opcode.DATA_END, 4)


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


def channel_kind(out: Scan, cid: int) -> str | None:
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


def file_record(out: Scan, rec, time_range) -> str | None:
    """File one record (a chunk: its records, unless outside ``time_range``); returns why a chunk is damaged."""
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
            file_record(out, r, time_range)
    elif isinstance(rec, Channel):
        out.channels[rec.id] = rec
    elif isinstance(rec, Schema):
        out.schemas[rec.id] = rec
    elif isinstance(rec, Metadata):
        out.metadata[rec.name] = dict(rec.metadata)
    elif isinstance(rec, Header):
        out.library = rec.library
    return None


def check_data_end(data: bytes, out: Scan, crc: int, start: int, time_range) -> None:
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
