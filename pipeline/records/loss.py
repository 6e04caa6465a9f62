"""What a damaged or truncated record file lost, in runs and episodes.

The expected episodes come from the file's own metadata: ``runs`` and ``episodes`` of the recorded
config (the trials stage records both), or, without ``episodes``, the closing record's episode
count divided by the runs. Missing = expected - read; each contiguous missing range of a run is
put down to the damaged part whose messages' log-time span holds the range's first episode (an
episode batch is stamped at its first episode, so a lost batch starts a missing range inside the
span of the chunk that held it). Ranges no damaged part explains are "not in the file" for an
unfinished file (a killed run stops there) and "lost" otherwise.
"""

from __future__ import annotations

from itertools import groupby

import numpy as np

from . import schema as S
from .scan import Damage, Scan

#: Damage kinds that mean the bytes are wrong (a file with any of these is DAMAGED, not just cut).
DAMAGE_KINDS = frozenset({"chunk", "bytes", "metadata", "summary", "decode", "data"})
_MAX_RANGES = 6


def expected_shape(
    config: dict | None, obstacles: dict, closed: dict | None
) -> tuple[int | None, int | None]:
    """(runs, episodes per run) the file should hold, when its metadata says."""

    def number(v) -> int | None:
        return int(v) if type(v) is int or isinstance(v, str) and v.isdigit() else None

    cfg, closed = config or {}, closed or {}
    runs, episodes, n = (
        number(cfg.get("runs")),
        number(cfg.get("episodes")),
        number(closed.get("episodes")),
    )
    if runs is None:
        runs = len(obstacles) or None
    if (
        episodes is None
        and runs
        and closed.get("complete") == "true"
        and n is not None
        and n % runs == 0
    ):
        episodes = n // runs
    return runs, episodes


def describe(rgs: list[tuple[int, int, int]], per_run: int | None) -> str:
    """``run 1 episodes 40-59, runs 2-3 (all 50 episodes each)``: adjacent ranges joined, long lists shortened."""
    joined: list[tuple[int, int, int]] = []
    for r, a, b in sorted(rgs):
        if joined and joined[-1][0] == r and joined[-1][2] + 1 == a:
            a = joined.pop()[1]
        joined.append((r, a, b))
    parts = []
    for (_, a, b), group in groupby(
        enumerate(joined), lambda x: (x[1][0] - x[0], x[1][1], x[1][2])
    ):
        rs = [r for _, (r, _, _) in group]
        runs, each = (f"runs {rs[0]}-{rs[-1]}", " each") if len(rs) > 1 else (f"run {rs[0]}", "")
        eps = f"episode {a}" if a == b else f"episodes {a}-{b}"
        full = per_run is not None and a == 0 and b == per_run - 1
        parts.append(f"{runs} (all {per_run} episodes{each})" if full else f"{runs} {eps}{each}")
    if len(parts) > _MAX_RANGES:
        parts = parts[: _MAX_RANGES - 1] + [f"and {len(parts) - _MAX_RANGES + 1} more ranges"]
    return ", ".join(parts) + (
        f" ({sum(b - a + 1 for _, a, b in joined)} episodes)" if len(joined) > 1 else ""
    )


def account(
    sc: Scan,
    read_runs: np.ndarray,
    read_eps: np.ndarray,
    *,
    runs: int | None,
    per_run: int | None,
    unfinished: bool,
    window=None,
    batch_size: int | None = None,
    counts: dict | None = None,
) -> tuple:
    """(episodes expected, when known; the warning's sentences; a short headline): every missing range put down
    to the damaged part that held it. ``batch_size``: the episodes of every sink batch, when uniform (a lost
    batch holds that many); ``counts``: kind -> (read, expected) messages, when the file says."""
    read = np.unique(read_runs.astype(np.int64) << 32 | read_eps.astype(np.int64))
    rr, re_ = read >> 32, read & 0xFFFFFFFF
    last = np.r_[rr[1:] != rr[:-1], True][: len(read)]  # the last episode read of each run
    last_read = dict(zip(rr[last].tolist(), re_[last].tolist()))
    # expected: per run, episodes first..end-1 (the runs x episodes grid, in the window); the shape unknown, each
    # run up to its last episode read. Ranges, not every episode, so a long killed run is cheap to account for
    known = runs is not None and per_run is not None
    grid = (
        [(r, 0, per_run) for r in range(runs)]
        if known
        else [(r, 0, e + 1) for r, e in last_read.items()]
    )
    if known and window is not None:
        k0, k1 = ((r << 32) + e for r, e, _ in map(S.split_log_time, window))
        grid = [(r, max(a, k0 - (r << 32)), min(b, k1 - (r << 32))) for r, a, b in grid]
    grid = [(r, a, b) for r, a, b in grid if a < b and (runs is None or 0 <= r < runs)]
    expected = sum(b - a for _, a, b in grid) if known else None
    if not sc.damage and (expected is None or len(read) == expected):
        return expected, [], ""
    missing = []  # (run, first, last) ranges of the grid that were not read
    for r, a, b in grid:
        got = re_[np.searchsorted(read, (r << 32) + a) : np.searchsorted(read, (r << 32) + b)]
        missing += [
            (r, int(lo), int(hi) - 1) for lo, hi in zip(np.r_[a, got + 1], np.r_[got, b]) if hi > lo
        ]
    spanned = [
        d
        for d in sc.damage
        if d.span is not None and d.kind in ("chunk", "bytes", "truncated", "decode")
    ]
    # what no span holds: the tail of an unfinished file (a truncation's), else a gap (a damaged record's)
    tail = next((d for d in sc.damage if d.kind == "truncated"), None) or Damage(
        "tail", "not recorded (the trials stopped before them)"
    )
    gaps = next(
        (d for d in sc.damage if d.span is None and d.kind in ("chunk", "bytes")), None
    ) or Damage("gaps", "missing, with no damaged part found to explain it")
    # a missing range is split where a batch of a lost chunk starts (its message index records say)
    stamp_owner = {t: d for d in sc.damage for t in d.held.get("episode batches", ())}
    stamps = np.array(
        sorted({r << 32 | e for r, e, _ in map(S.split_log_time, stamp_owner)}), np.int64
    )
    for r, lo, b in missing:
        while lo <= b:
            i = np.searchsorted(stamps, r << 32 | lo, side="right")
            hi = min(b, int(stamps[i]) - (r << 32) - 1) if i < len(stamps) else b
            t = S.log_time_ns(r, lo)
            owner, start = (
                stamp_owner.get(t),
                lo,
            )  # start: of the owner's last batch of the run, when known
            if owner is None:
                owner = next((d for d in spanned if d.span[0] <= t <= d.span[1]), None)
                r_end, e_end, _ = (
                    S.split_log_time(owner.span[1]) if owner is not None else (None, 0, 0)
                )
                start = e_end if r_end == r else None  # lo <= e_end: t is in the span
                owner = owner or (tail if unfinished and lo > last_read.get(r, -1) else gaps)
            if batch_size and start is not None:
                hi = min(hi, start + batch_size - 1)  # a lost batch holds batch_size episodes
            owner.lost.append((r, lo, hi))
            lo = hi + 1
    lost, absent, sentences = [], [], []
    for d in sc.damage + [d for d in (tail, gaps) if d.kind in ("tail", "gaps") and d.lost]:
        (absent if d.kind in ("truncated", "tail") else lost).extend(d.lost)
        how = {"tail": ":", "gaps": ":", "truncated": "; missing"}.get(d.kind, ": lost")
        none = (
            ": no episode lost"
            if d.kind in ("chunk", "bytes", "decode") and expected is not None
            else ""
        )
        sentences.append(f"{d.what}{how} {describe(d.lost, per_run)}" if d.lost else d.what + none)
    msgs = ", ".join(
        f"{exp - got} of {exp} {kind}" for kind, (got, exp) in (counts or {}).items() if got < exp
    )
    sentences += [f"messages lost: {msgs}"] if msgs else []
    heads = [
        f"{word} {describe(rgs, per_run)}"
        for word, rgs in (("lost", lost), ("missing", absent))
        if rgs
    ]
    return expected, sentences, "; ".join(heads + ([f"lost {msgs}"] if msgs else []))
