"""What every fault case checks: one line on stderr naming the problem, and nothing lost."""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: A trial small enough for a fault case.
FAST = ["runs=2", "episodes=4", "progress=false"]


def one_line_error(out, *words, code=2):
    """``out`` (a finished command) exited ``code`` with one line on stderr holding ``words``."""
    assert out.returncode == code, (out.returncode, out.stderr[-2000:])
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def digest(folder: Path) -> dict:
    """Every file under ``folder`` with its SHA-256: equal before and after means nothing lost."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def sha(path: Path) -> str:
    """The SHA-256 of one file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def trials_process(*args: str) -> subprocess.Popen:
    """``python -m pipeline trials <args>`` started in a child process (stdout, stderr piped)."""
    return subprocess.Popen(
        [sys.executable, "-m", "pipeline", "trials", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
