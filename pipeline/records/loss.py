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

import bisect
from dataclasses import dataclass, field

import numpy as np

from . import schema as S
from .scan import Damage, Scan

#: Damage kinds that mean the bytes are wrong (a file with any of these is DAMAGED, not just cut).
DAMAGE_KINDS = frozenset({"chunk", "bytes", "metadata", "summary", "decode", "data"})
_MAX_RANGES = 6


def _int(v) -> int | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, int):
        return v
    if isinstance(v, str) and v.isdigit():
        return int(v)
    return None


def expected_shape(config: dict | None, obstacles: dict, closed: dict | None) -> tuple[int | None, int | None]:
    """(runs, episodes per run) the file should hold, when its metadata says."""
    cfg = config or {}
    runs = _int(cfg.get("runs"))
    if runs is None and obstacles:
        runs = len(obstacles)
    episodes = _int(cfg.get("episodes"))
    closed = closed or {}
    n_closed = _int(closed.get("episodes"))
    if episodes is None and runs and closed.get("complete") == "true" and n_closed is not None \
            and n_closed % runs == 0:
        episodes = n_closed // runs
    return runs, episodes


def ranges(runs: np.ndarray, eps: np.ndarray) -> list[tuple[int, int, int]]:
    """Contiguous (run, first, last) episode ranges of the given (run, episode) pairs."""
    if not len(runs):
        return []
    key = np.unique(runs.astype(np.int64) << 32 | eps.astype(np.int64))
    r, e = key >> 32, key & 0xFFFFFFFF
    breaks = np.flatnonzero((np.diff(r) != 0) | (np.diff(e) != 1)) + 1
    starts = np.r_[0, breaks]
    stops = np.r_[breaks, len(key)] - 1
    return [(int(r[a]), int(e[a]), int(e[b])) for a, b in zip(starts, stops)]


def describe(rgs: list[tuple[int, int, int]], per_run: int | None) -> str:
    """``run 1 episodes 40-59, runs 2-3 (all 50 episodes each)``: consecutive runs missing the same
    episodes are one part; long lists are shortened."""
    parts: list[str] = []
    i = 0
    while i < len(rgs):
        r, a, b = rgs[i]
        j = i
        while j + 1 < len(rgs) and rgs[j + 1] == (rgs[j][0] + 1, a, b):
            j += 1
        runs = f"runs {r}-{rgs[j][0]}" if j > i else f"run {r}"
        each = " each" if j > i else ""
        if per_run is not None and a == 0 and b == per_run - 1:
            parts.append(f"{runs} (all {per_run} episodes{each})")
        elif a == b:
            parts.append(f"{runs} episode {a}{each}")
        else:
            parts.append(f"{runs} episodes {a}-{b}{each}")
        i = j + 1
    total = sum(b - a + 1 for _, a, b in rgs)
    if len(parts) > _MAX_RANGES:
        parts = parts[:_MAX_RANGES - 1] + [f"and {len(parts) - _MAX_RANGES + 1} more ranges"]
    return ", ".join(parts) + (f" ({total} episodes)" if len(rgs) > 1 else "")


@dataclass
class Loss:
    """The loss accounting of one file."""

    expected: int | None  # episodes the file should hold (in the requested window), when known
    read: int
    sentences: list[str] = field(default_factory=list)  # the warning, one sentence per finding
    lost: list[tuple[int, int, int]] = field(default_factory=list)  # damaged away
    absent: list[tuple[int, int, int]] = field(default_factory=list)  # not in an unfinished file
    headline: str = ""  # short: what was lost, for the one-line listing


def _grid(runs: int, per_run: int, window) -> tuple[np.ndarray, np.ndarray]:
    r = np.repeat(np.arange(runs, dtype=np.int64), per_run)
    e = np.tile(np.arange(per_run, dtype=np.int64), runs)
    if window is not None:
        t = r * S.RUN_NS + e * S.EPISODE_NS
        keep = (t >= window[0]) & (t < window[1])
        r, e = r[keep], e[keep]
    return r, e


def account(sc: Scan, read_runs: np.ndarray, read_eps: np.ndarray, *, runs: int | None,
            per_run: int | None, unfinished: bool, window=None, batch_size: int | None = None,
            counts: dict[str, tuple[int, int]] | None = None) -> Loss:
    """Compare what was read with what the file should hold and put every missing range down to the
    damaged part that held it. ``batch_size``: the episodes of every sink batch, when uniform (a
    lost batch then holds that many); ``counts``: kind -> (read, expected) messages (pictures,
    substitutions) when the file's statistics or closing record say how many there were."""
    read_key = np.unique(read_runs.astype(np.int64) << 32 | read_eps.astype(np.int64))
    if runs is not None and per_run is not None:
        er, ee = _grid(runs, per_run, window)
        expected = len(er)
        if len(read_key) == expected and not sc.damage:
            return Loss(expected, len(read_key))
        ekey = er << 32 | ee
        miss = ekey[~np.isin(ekey, read_key)]
    else:
        expected = None
        if not sc.damage:
            return Loss(None, len(read_key))
        # gaps before the last read episode of each run; runs with nothing read, when runs is known
        rr, re_ = read_key >> 32, read_key & 0xFFFFFFFF
        parts = []
        for r in (range(runs) if runs is not None else np.unique(rr)):
            have = re_[rr == r]
            if len(have):
                allowed = np.arange(int(have.max()) + 1, dtype=np.int64)
                parts.append(np.int64(r) << 32 | allowed[~np.isin(allowed, have)])
        miss = np.concatenate(parts) if parts else np.zeros(0, np.int64)
    loss = Loss(expected, len(read_key))
    rgs = ranges(miss >> 32, miss & 0xFFFFFFFF)
    ends = np.flatnonzero(np.r_[np.diff(read_key >> 32) != 0, True]) if len(read_key) else np.zeros(0, np.int64)
    last_read = dict(zip((read_key[ends] >> 32).tolist(), (read_key[ends] & 0xFFFFFFFF).tolist()))
    spanned = [d for d in sc.damage if d.span is not None and d.kind in ("chunk", "bytes", "truncated", "decode")]
    spanless = [d for d in sc.damage if d.span is None and d.kind in ("chunk", "bytes")]
    truncation = next((d for d in sc.damage if d.kind == "truncated"), None)
    # the exact batch stamps of lost chunks (from their message index records): a missing range
    # is split where a batch of another lost chunk starts
    stamp_owner = {t: d for d in sc.damage for t in d.batch_stamps}
    stamps_of_run: dict[int, list[int]] = {}
    for t in sorted(stamp_owner):
        r, e, _ = S.split_log_time(t)
        stamps_of_run.setdefault(r, []).append(e)
    for d in sc.damage:
        d.lost = []
    tail, gaps = [], []
    for r, a, b in rgs:
        run_stamps = stamps_of_run.get(r, [])
        lo = a
        while lo <= b:
            i = bisect.bisect_right(run_stamps, lo)
            hi = min(b, run_stamps[i] - 1) if i < len(run_stamps) else b
            t = S.log_time_ns(r, lo)
            owner = stamp_owner.get(t)
            if owner is not None and batch_size:
                hi = min(hi, lo + batch_size - 1)  # a lost batch holds batch_size episodes
            if owner is None:
                owner = next((d for d in spanned if d.span[0] <= t <= d.span[1]), None)
                if owner is not None and batch_size:
                    r_end, e_end, _ = S.split_log_time(owner.span[1])
                    if r_end == r:  # its last batch of this run starts by e_end
                        hi = min(hi, max(lo, e_end) + batch_size - 1)
            if owner is not None:
                owner.lost.append((r, lo, hi))
            elif unfinished and lo > last_read.get(r, -1):
                tail.append((r, lo, hi))
            else:
                gaps.append((r, lo, hi))
            lo = hi + 1
    if gaps and spanless:
        spanless[0].lost.extend(gaps)
        gaps = []
    tail, gaps = _merged(tail), _merged(gaps)
    for d in sc.damage:
        d.lost = _merged(d.lost)
        s = d.what
        if d.kind == "truncated":
            held = _merged(d.lost + tail)
            if held:
                s += f"; missing {describe(held, per_run)}"
            loss.absent.extend(held)
        elif d.lost:
            s += f": lost {describe(d.lost, per_run)}"
            loss.lost.extend(d.lost)
        elif d.kind in ("chunk", "bytes", "decode") and expected is not None:
            s += ": no episode lost"
        loss.sentences.append(s)
    if tail and truncation is None:
        loss.sentences.append(f"not recorded (the trials stopped before them): {describe(tail, per_run)}")
        loss.absent.extend(tail)
    if gaps:
        loss.sentences.append(f"missing, with no damaged part found to explain it: {describe(gaps, per_run)}")
        loss.lost.extend(gaps)
    msgs = [f"{exp - got} of {exp} {kind}" for kind, (got, exp) in (counts or {}).items() if got < exp]
    if msgs:
        loss.sentences.append("messages lost: " + ", ".join(msgs))
    heads = []
    if loss.lost:
        heads.append("lost " + describe(_merged(loss.lost), per_run))
    if loss.absent:
        heads.append("missing " + describe(_merged(loss.absent), per_run))
    if msgs:
        heads.append("lost " + ", ".join(msgs))
    loss.headline = "; ".join(heads)
    return loss


def _merged(rgs: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    out: list[tuple[int, int, int]] = []
    for r, a, b in sorted(rgs):
        if out and out[-1][0] == r and out[-1][2] + 1 == a:
            out[-1] = (r, out[-1][1], b)
        else:
            out.append((r, a, b))
    return out


def damaged(damage: list[Damage]) -> bool:
    return any(d.kind in DAMAGE_KINDS for d in damage)
