"""Atomic file output: the one way the pipeline replaces a file.

A file is written under a temporary name in its final folder and moved into place with
``os.replace`` only when complete, so a reader (or the next stage) never sees half a file, and a
failed write leaves the previous version untouched.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

from pipeline.errors import UserError

#: A full disk or quota, and a folder or file system that cannot be written.
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)
NOT_WRITABLE = (errno.EROFS, errno.EACCES, errno.EPERM)


class DiskError(UserError):
    """A write that failed for lack of space (``full``) or of permission; the message names the
    folder, ``needed`` says what the write needs when known (both kept across processes)."""

    def __init__(self, message: str, needed: str = "", full: bool = True):
        super().__init__(message, needed, full)
        self.needed, self.full = needed, full

    def __str__(self) -> str:
        return self.args[0]


def size_text(n: float) -> str:
    """``n`` bytes in the largest unit that keeps a number >= 1 (``3.1 MB``)."""
    for unit in ("B", "kB", "MB", "GB"):
        if abs(n) < 1000 or unit == "GB":
            return f"{n:,.0f} {unit}" if unit == "B" else f"{n:,.1f} {unit}"
        n /= 1000
    raise AssertionError  # unreachable


def free_space(folder: str | Path) -> int:
    """Bytes free on the file system of ``folder`` (or of its nearest existing parent)."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return shutil.disk_usage(folder).free


def disk_problem(exc: OSError, folder: str | Path, needed: str = "") -> DiskError | None:
    """One line for a full or read-only disk, naming ``folder``, its free space and ``needed``
    (what the write needs, when known); None for any other error."""
    if exc.errno not in DISK_FULL + NOT_WRITABLE:
        return None
    return disk_error(folder, needed, exc.errno in DISK_FULL, exc.strerror)


def disk_error(folder: str | Path, needed: str, full: bool, why: str = "") -> DiskError:
    """The one line of :func:`disk_problem` (the free space is measured now)."""
    need = f"; {needed}" if needed else ""
    if full:
        free = size_text(free_space(folder))
        text = f"no space left on the device of {folder} ({free} free{need}); free some space or"
    else:
        text = f"cannot write into {folder} ({why or 'not writable'}{need});"
    return DiskError(f"{text} choose another folder", needed, full)


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


@contextmanager
def exclusive_folder(folder: str | Path, what: str = "out") -> Iterator[Path]:
    """Hold ``folder`` for one writer: create it if needed, refuse at once (``UserError`` naming
    ``what``) when it is a file, not writable, or held by another process."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"config key '{what}': {folder} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle = open(folder / ".lock", "a+")
    except OSError as exc:
        raise UserError(
            f"config key '{what}': cannot write into {folder} ({exc.strerror})"
        ) from None
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise UserError(
                f"config key '{what}': {folder} is being written by another process; "
                "wait for it, or choose another folder"
            ) from None
        yield folder
    finally:
        (folder / ".lock").unlink(missing_ok=True)
        handle.close()


def swap_in(staging: Path, target: Path) -> None:
    """Move every entry of ``staging`` into ``target``, replacing entries of the same name, then
    remove ``staging``. A folder being replaced is moved aside first and deleted last."""
    aside = []
    for entry in sorted(staging.iterdir()):
        if entry.name.startswith(".old-"):
            continue
        dest = target / entry.name
        if dest.is_dir() and not dest.is_symlink():
            old = staging / f".old-{entry.name}"
            os.replace(dest, old)
            aside.append(old)
        os.replace(entry, dest)
    shutil.rmtree(staging)


def write_index(folder: str | Path, path: str | Path) -> Path:
    """The SHA-256 of every file under ``folder`` (by relative path, sorted; hidden entries left
    out) written to ``path`` as JSON. A small committed stand-in for a DVC-cached folder: stages
    downstream declare it as their dependency, so ``dvc repro --dry`` can hash it on a fresh clone
    where the folder does not exist yet (dvc.yaml)."""
    import hashlib

    folder = Path(folder)
    files = sorted(
        p
        for p in folder.rglob("*")
        if p.is_file() and not p.relative_to(folder).as_posix().startswith(".")
    )
    index = {}
    for p in files:
        digest = hashlib.sha256()
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
        index[p.relative_to(folder).as_posix()] = digest.hexdigest()
    return write_json_atomic(path, {"folder": folder.as_posix(), "files": index})
