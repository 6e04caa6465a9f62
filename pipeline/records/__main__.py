"""``python -m pipeline.records <file.mcap | folder> [--runs]``: what record files hold (config,
completeness, runs, episodes, collisions, what a damaged or cut file lost), one line a file: the
quickest way to find the run and episode to replay. A folder lists every ``*.mcap`` and
``*.mcap.partial`` file under it (``.staging-*`` folders of interrupted trials included), those of
killed runs marked PARTIAL; a file that cannot be read is named with its problem in one line on
stderr. Exit status: 0, every file listed; 1, some files of the folder could not be read (the
others are listed); 2, nothing could be read, or no such file or folder; 141, the pipe was closed.
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

from pipeline.errors import UserError

from .loss import expected_shape
from .reader import RecordsNotFound, RecordsWarning, find_record_files, read_records
from .scan import RecordsError


def _describe(path: Path, per_run: bool) -> None:
    """The file's warnings, then one line (and with ``per_run`` one per run); RecordsError if unusable."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordsWarning)
        recs = read_records(path, pictures=False)
    (name, meta), = recs.files.items()
    if meta.unusable:  # our magic bytes, then nothing readable: a cut copy
        raise RecordsError(meta.unusable)
    for w in caught:
        if issubclass(w.category, RecordsWarning):
            print(f"warning: {w.message}")
    eps, cfg = recs.episodes, meta.config or {}
    what = ", ".join(f"{k}={cfg[k]}" for k in ("experiment", "method", "maze", "seed")
                     if k in cfg and not isinstance(cfg[k], dict))
    of = lambda n, expected, unit: f"{n} {unit}" if expected in (None, n) else f"{n} of {expected} {unit}"  # noqa: E731
    runs = expected_shape(meta.config, meta.obstacles, meta.closed)[0]
    print(f"{name}: {meta.status}; {of(eps.run.nunique(), runs, 'runs')}, "
          f"{of(len(eps), meta.expected_episodes, 'episodes')}, {int(eps.collisions.sum())} collisions"
          + "".join(f"; {x}" for x in (meta.lost, what) if x))
    if per_run and len(eps):
        print(eps.groupby("run").agg(episodes=("episode", "size"), first=("episode", "min"), last=("episode", "max"),
                                     collisions=("collisions", "sum"), goals=("reached_goal", "sum"),
                                     steps=("steps", "sum")).to_string())


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m pipeline.records", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("path", type=Path, help="an .mcap (or .mcap.partial) record file, or a folder of them")
    ap.add_argument("--runs", action="store_true", help="one line per run (episodes, collisions, goals)")
    args, bad = ap.parse_args(argv), 0
    path = args.path
    try:
        files = find_record_files(path, every_partial=True) if path.is_dir() else [path] if path.exists() else []
        if not files:
            raise RecordsNotFound(f"{path}: " + ("no record files (*.mcap, *.mcap.partial) under this folder"
                                                 if path.is_dir() else "no such record file or folder"))
        for f in files:
            try:
                _describe(f, args.runs)
            except RecordsError as e:
                if len(files) == 1:
                    raise
                print(f"error: {e}", file=sys.stderr, flush=True)
                bad += 1
        if bad == len(files):
            raise RecordsError(f"{path}: none of its {len(files)} record files could be read")
        print("replay one: python -m pipeline replay file=<file> run=<run> episode=<episode>")
        sys.stdout.flush()
    except BrokenPipeError:  # the reader went away (``| head``): stop quietly, as a shell reports SIGPIPE
        try:  # the interpreter's last flush must not fail again
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        raise SystemExit(141) from None
    except UserError as exc:
        sys.stdout.flush()
        print(f"error: {exc}", file=sys.stderr, flush=True)
        raise SystemExit(2) from None
    if bad:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
