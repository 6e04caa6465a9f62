"""What a damaged or truncated record file lost, in runs and episodes (docs/records.md "Damaged and
truncated files").

Expected: the ``runs`` x ``episodes`` grid of the recorded config (the trials stage records both),
or, without ``episodes``, the closing record's episode count divided by the runs. Missing =
expected - read, as ranges per run. A range is *lost* (damage took it) when episodes after it were
read, when the file was finished, or when its first episode's time stamp lies in a damaged chunk's
span; otherwise it was *not recorded* (an unfinished file: the trials stopped before it).
"""

from __future__ import annotations

from itertools import groupby

import numpy as np

from . import schema as S

_MAX_RANGES = 6
Ranges = list[tuple[int, int, int]]  # (run, first episode, last episode)


def expected_shape(config: dict | None, obstacles: dict, closed: dict | None) -> tuple:
    """(runs, episodes per run) the file should hold, when its metadata says."""

    def number(v) -> int | None:
        return int(v) if type(v) is int or isinstance(v, str) and v.isdigit() else None

    cfg, closed = config or {}, closed or {}
    runs, episodes, n = (
        number(x) for x in (cfg.get("runs"), cfg.get("episodes"), closed.get("episodes"))
    )
    runs = runs if runs is not None else len(obstacles) or None
    if (
        episodes is None
        and runs
        and closed.get("complete") == "true"
        and n is not None
        and n % runs == 0
    ):
        episodes = n // runs
    return runs, episodes


def describe(ranges: Ranges, per_run: int | None) -> str:
    """``run 1 episodes 40-59, runs 2-3 (all 50 episodes each)``: adjacent ranges joined."""
    joined: Ranges = []
    for r, a, b in sorted(ranges):
        if joined and joined[-1][0] == r and joined[-1][2] + 1 == a:
            a = joined.pop()[1]
        joined.append((r, a, b))
    parts = []
    for (_, a, b), group in groupby(
        enumerate(joined), lambda x: (x[1][0] - x[0], x[1][1], x[1][2])
    ):
        rs = [r for _, (r, _, _) in group]
        runs, each = (f"runs {rs[0]}-{rs[-1]}", " each") if len(rs) > 1 else (f"run {rs[0]}", "")
        full = per_run is not None and a == 0 and b == per_run - 1
        eps = f"episode {a}" if a == b else f"episodes {a}-{b}"
        parts.append(f"{runs} (all {per_run} episodes{each})" if full else f"{runs} {eps}{each}")
    if len(parts) > _MAX_RANGES:
        parts = parts[: _MAX_RANGES - 1] + [f"and {len(parts) - _MAX_RANGES + 1} more ranges"]
    total = sum(b - a + 1 for _, a, b in joined)
    return ", ".join(parts) + (f" ({total} episodes)" if len(joined) > 1 else "")


def account(read_runs, read_eps, *, runs, per_run, finished: bool, spans=(), window=None) -> tuple:
    """(episodes expected or None, lost ranges, not-recorded ranges) of a file of which the
    episodes ``(read_runs, read_eps)`` were read; ``spans``: log-time spans of damaged chunks;
    ``window``: the log-time range asked for. Ranges, not episodes: a long killed run is cheap."""
    read = np.unique(np.asarray(read_runs, np.int64) << 32 | np.asarray(read_eps, np.int64))
    rr, re_ = read >> 32, read & 0xFFFFFFFF
    last = dict(zip(rr.tolist(), re_.tolist()))  # each run's last episode read (sorted: the last)
    known = runs is not None and per_run is not None
    grid = (
        [(r, 0, per_run) for r in range(runs)]
        if known
        else [(r, 0, e + 1) for r, e in last.items()]
    )
    if window is not None:
        k0, k1 = ((r << 32) + e for r, e, _ in map(S.split_log_time, window))
        grid = [(r, max(a, k0 - (r << 32)), min(b, k1 - (r << 32))) for r, a, b in grid]
    grid = [(r, a, b) for r, a, b in grid if a < b]
    lost: Ranges = []
    absent: Ranges = []
    for r, a, b in grid:
        got = re_[np.searchsorted(read, (r << 32) + a) : np.searchsorted(read, (r << 32) + b)]
        for lo, hi in zip(np.r_[a, got + 1].tolist(), np.r_[got, b].tolist()):
            if hi > lo:
                t = S.log_time_ns(r, lo)
                damaged = finished or lo < last.get(r, -1) or any(s0 <= t <= s1 for s0, s1 in spans)
                (lost if damaged else absent).append((r, lo, hi - 1))
    return (sum(b - a for _, a, b in grid) if known else None), lost, absent
