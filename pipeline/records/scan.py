"""What survives of an MCAP record file, read through the mcap package (docs/records.md "Damaged and truncated
files"): with mcap's seeking reader when its summary is intact, else (or when that finds damage) front to back
(``walk.py``). Each damaged or missing part is a :class:`Damage`; a file with nothing to read raises
:class:`RecordsError`.
"""

from __future__ import annotations

import contextlib
import io
import struct
import zlib
from pathlib import Path

from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE, make_reader

from .scanned import (
    DATA_END_HEAD,
    PICTURE_TOPICS,
    WRITER_CHANNELS,
    Damage,
    RecordsError,
    Scan,
    check_data_end,
    file_record,
    message_kind,
)
from .walk import walk

__all__ = ["WRITER_CHANNELS", "Damage", "RecordsError", "Scan", "message_kind", "scan"]

MAGIC = b"\x89MCAP0\r\n"
_FOOTER = struct.Struct("<BQQQI")
_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"PK\x03\x04", "a zip archive"),
    (b"\x1f\x8b", "a gzip file"),
    (b"\x28\xb5\x2f\xfd", "a zstd file"),
    (b"SQLite format 3\x00", "an SQLite database"),
    (b"RRF", "a Rerun .rrd file"),
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
    walk(data, out, end, time_range)
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
    pictures = {t for t in topics if t.startswith(PICTURE_TOPICS)}
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
        file_record(out, rec, None)
    if data[end - 13 : end - 4] != DATA_END_HEAD:
        raise TypeError("no data-end record before the summary")
    check_data_end(data, out, int.from_bytes(data[end - 4 : end], "little"), end - 13, time_range)
    out.complete = not out.damage
    return out
