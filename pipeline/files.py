"""Atomic file output: the one way the pipeline replaces a file.

A file is written under a temporary name in its final folder and moved into place with
``os.replace`` only when complete, so a reader (or the next stage) never sees half a file, and a
failed write leaves the previous version untouched.
"""
from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO, Iterator


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_output(path: str | Path, *, fsync: bool = True) -> Iterator[BinaryIO]:
    """``with atomic_output(p) as f: f.write(...)``: ``p`` appears, complete, when the block ends
    without an exception; otherwise the temporary file is removed and ``p`` is unchanged.
    ``fsync=False`` skips flushing to the disk (many small files that are cheap to remake)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            if fsync:
                os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_atomic(path: str | Path, data: bytes | str, *, fsync: bool = True) -> Path:
    """Write ``data`` (bytes, or text as UTF-8) to ``path`` atomically."""
    with atomic_output(path, fsync=fsync) as f:
        f.write(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


def write_json_atomic(path: str | Path, data: Any, *, sort_keys: bool = False) -> Path:
    """JSON (indent 2, final newline) written atomically."""
    return write_atomic(path, json.dumps(data, indent=2, sort_keys=sort_keys) + "\n")
