"""Atomic file output: the one way the pipeline replaces a file.

A file is written under a temporary name in its final folder and moved into place with
``os.replace`` only when complete, so a reader (or the next stage) never sees half a file, and a
failed write leaves the previous version untouched.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO


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
    from pipeline.errors import UserError

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
