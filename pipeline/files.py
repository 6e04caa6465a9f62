"""Atomic file output: the one way the pipeline replaces a file.

A file is written under a temporary name in its final folder and moved into place with
``os.replace`` only when complete, so a reader (or the next stage) never sees half a file, and a
failed write leaves the previous version untouched.

A folder is written by one process at a time (:func:`exclusive_folder`), and a process builds
in its own work folder (:func:`work_folder`) that no other process removes while it lives.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import socket
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
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


def write_json_atomic(
    path: str | Path, data: Any, *, sort_keys: bool = False, fsync: bool = True
) -> Path:
    """JSON (indent 2, final newline) written atomically (``fsync``: as :func:`atomic_output`)."""
    return write_atomic(path, json.dumps(data, indent=2, sort_keys=sort_keys) + "\n", fsync=fsync)


# ------------------------------------------------------------------ owners: locks, work folders
#: The file of a work folder (:func:`claim_folder`) naming its process; :func:`swap_in` leaves it.
OWNER_FILE = ".owner"


def process_start(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks after boot: field 22 of ``/proc/<pid>/stat``);
    ``-1`` where there is no ``/proc`` but the process exists; None when there is no such process
    (a zombie has ended too)."""
    if pid <= 0:
        return None
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        if Path("/proc/self/stat").exists():
            return None
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:
            pass
        return -1
    return None if fields[0] in ("Z", "X") else int(fields[19])


@dataclass(frozen=True)
class Owner:
    """The process a lock or a work folder belongs to: its pid, start time (:func:`process_start`)
    and host. The pid alone is not enough: the system gives an ended process's pid to a new one."""

    pid: int
    start: int | None = None
    host: str = ""

    @classmethod
    def me(cls) -> Owner:
        return cls(os.getpid(), process_start(os.getpid()), socket.gethostname())

    @classmethod
    def parse(cls, text: str) -> Owner | None:
        """The owner :meth:`text` wrote; None for anything else (an empty or foreign file)."""
        try:
            d = json.loads(text)
            start = d.get("start")
            return cls(int(d["pid"]), start if isinstance(start, int) else None, str(d["host"]))
        except (ValueError, TypeError, KeyError, AttributeError):
            return None

    def text(self) -> str:
        return json.dumps({"pid": self.pid, "start": self.start, "host": self.host}) + "\n"

    def alive(self) -> bool:
        """Whether the process runs: its pid exists, with the same start time where both are
        known. A process of another host is taken to be alive (its pids cannot be seen here)."""
        if self.host and self.host != socket.gethostname():
            return True
        now = process_start(self.pid)
        return now is not None and (now == -1 or self.start in (None, -1) or now == self.start)


@contextmanager
def exclusive_folder(folder: str | Path, what: str = "out") -> Iterator[Path]:
    """Hold ``folder`` for one writer: create it if needed, refuse at once (``UserError`` naming
    ``what``) when it is a file, not writable, or held by another live process.

    The hold is ``<folder>/.lock``: ``flock``-ed by its owner while it lives (the kernel lets go
    when it dies, however), naming it (:class:`Owner`), and removed only by it. A lock left by a
    process that has ended is taken over; ``flock`` lets one taker win. A refused process only
    reads the lock."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UserError(f"config key '{what}': {folder} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd = _take_lock(folder / ".lock", what)
    except OSError as exc:
        raise UserError(
            f"config key '{what}': cannot write into {folder} ({exc.strerror})"
        ) from None
    try:
        yield folder
    finally:
        try:
            if _same_file(fd, folder / ".lock"):
                (folder / ".lock").unlink()
        finally:
            os.close(fd)


def _take_lock(path: Path, what: str) -> int:
    """``path`` opened, ``flock``-ed and naming this process; ``UserError`` when a live process
    holds it."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise _held(path.parent, what, _holder(fd)) from None
            if not _same_file(fd, path):  # its owner removed it as this process opened it
                os.close(fd)
                continue
            holder = Owner.parse(_read(fd))
            if holder is not None and holder.alive() and holder != Owner.me():
                raise _held(path.parent, what, holder)  # no flock on this file system
            os.ftruncate(fd, 0)
            os.pwrite(fd, Owner.me().text().encode(), 0)
            return fd
        except BaseException:
            os.close(fd)
            raise


def _read(fd: int) -> str:
    return os.pread(fd, 4096, 0).decode("utf-8", "replace")


def _same_file(fd: int, path: Path) -> bool:
    try:
        a, b = os.fstat(fd), os.stat(path)
    except FileNotFoundError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def _holder(fd: int) -> Owner | None:
    """The live owner of the lock open as ``fd``, given a moment to write its name when it has
    just taken the lock over; the name there, alive or not, after that."""
    for _ in range(25):
        owner = Owner.parse(_read(fd))
        if owner is not None and owner.alive():
            break
        time.sleep(0.02)
    return owner


def _held(folder: Path, what: str, owner: Owner | None) -> UserError:
    here = owner is None or owner.host in ("", socket.gethostname())
    by = "" if owner is None else f" (pid {owner.pid}{'' if here else ' on ' + owner.host})"
    ended = "" if here else f" (delete {folder / '.lock'} if that process has ended)"
    return UserError(
        f"config key '{what}': {folder} is being written by another process{by}; "
        f"wait for it, or choose another folder{ended}"
    )


def work_folder(parent: str | Path, prefix: str) -> Path:
    """``<parent>/<prefix>-<pid>``: where this process builds what :func:`swap_in` moves into
    ``parent`` when complete."""
    return Path(parent) / f"{prefix}-{os.getpid()}"


def claim_folder(folder: Path) -> Path:
    """Make ``folder`` (a :func:`work_folder`) new and empty, with a file naming this process
    (:data:`OWNER_FILE`), so that no other process takes it for abandoned while this one lives.
    What it held was left by an ended process: its pid is this one's."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    (folder / OWNER_FILE).write_text(Owner.me().text())
    return folder


def folder_owner(folder: Path) -> Owner:
    """Whose work folder ``folder`` is: its owner file, or (written before there was one, or
    being written) the pid of its name; pid 0, no process, for a name without one."""
    with contextlib.suppress(OSError):
        owner = Owner.parse((folder / OWNER_FILE).read_text())
        if owner is not None:
            return owner
    pid = folder.name.rsplit("-", 1)[-1]
    return Owner(int(pid) if pid.isdigit() else 0)


def abandoned(parent: str | Path, prefix: str) -> list[Path]:
    """The work folders ``<prefix>-*`` of ``parent`` whose process has ended (a killed or
    interrupted run's); a live process's folder is never among them."""
    found = sorted(p for p in Path(parent).glob(f"{prefix}-*") if p.is_dir())
    return [p for p in found if not folder_owner(p).alive()]


def remove_abandoned(parent: str | Path, prefix: str) -> list[Path]:
    """Remove the :func:`abandoned` work folders of ``parent``; the ones removed."""
    gone = abandoned(parent, prefix)
    for p in gone:
        shutil.rmtree(p, ignore_errors=True)
    return gone


def swap_in(staging: Path, target: Path) -> None:
    """Move every entry of ``staging`` into ``target``, replacing entries of the same name, then
    remove ``staging``. A folder being replaced is moved aside first and deleted last.

    What ``staging`` holds is flushed to the disk first (one ``sync`` for all its files, so the
    files written into it need not each be: ``fsync=False`` of :func:`atomic_output` and of the
    record writer), so a crash of the machine never leaves a renamed but empty result."""
    os.sync()
    aside = []
    for entry in sorted(staging.iterdir()):
        if entry.name.startswith(".old-") or entry.name == OWNER_FILE:
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
