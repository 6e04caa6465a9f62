"""``python -m pipeline.records <file.mcap | folder> [--runs]``: what a record file (or every record
file under a folder) holds: experiment config, completeness, runs, episodes, collisions, and what
was lost if a file is damaged or truncated. The quickest way to find the run and episode to replay.

A folder lists every ``*.mcap`` and ``*.mcap.partial`` file under it, one line each, the partial
files of killed or interrupted runs (also inside the ``.staging-*`` folders of interrupted trials)
marked PARTIAL. A file that cannot be read at all (empty, not MCAP, another program's MCAP) is
named with its problem in one line on stderr. Exit status: 0, every file listed; 1, some files of
the folder could not be read (the others are listed); 2, nothing could be read (the one file given,
or every file of the folder), or no such file or folder.
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


def _list(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if path.is_dir():
        files = find_record_files(path, every_partial=True)
        if not files:
            raise RecordsNotFound(f"{path}: no record files (*.mcap, *.mcap.partial) under this folder")
    elif path.exists():
        files = [path]
    else:
        raise RecordsNotFound(f"{path}: no such record file or folder")
    bad: list[str] = []
    for f in files:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RecordsWarning)
            try:
                recs = read_records(f, pictures=False)
                if recs.meta.unusable:  # our magic bytes, then nothing readable: a cut copy
                    raise RecordsError(recs.meta.unusable)
            except RecordsError as e:
                if len(files) == 1:
                    raise
                print(f"error: {e}", file=sys.stderr, flush=True)
                bad.append(str(e))
                continue
        for w in caught:
            if issubclass(w.category, RecordsWarning):
                print(f"warning: {w.message}")
        _describe(recs, args.runs)
    if len(bad) == len(files):
        raise RecordsError(f"{path}: none of its {len(files)} record files could be read")
    print("replay one: python -m pipeline replay file=<file> run=<run> episode=<episode>")
    return 1 if bad else 0


def _describe(recs, per_run: bool) -> None:
    for name, meta in recs.files.items():
        eps = recs.episodes[recs.episodes.file == name]
        cfg = meta.config or {}
        what = ", ".join(f"{k}={cfg[k]}" for k in ("experiment", "method", "maze", "seed") if k in cfg
                         and not isinstance(cfg[k], dict))
        runs, _ = expected_shape(meta.config, meta.obstacles, meta.closed)
        n_runs = eps.run.nunique()
        run_text = f"{n_runs} runs" if runs in (None, n_runs) else f"{n_runs} of {runs} runs"
        exp = meta.expected_episodes
        ep_text = f"{len(eps)} episodes" if exp in (None, len(eps)) else f"{len(eps)} of {exp} episodes"
        print(f"{name}: {meta.status}; {run_text}, {ep_text}, {int(eps.collisions.sum())} collisions"
              f"{'; ' + meta.lost if meta.lost else ''}{'; ' + what if what else ''}")
        if per_run and len(eps):
            per = eps.groupby("run").agg(episodes=("episode", "size"), first=("episode", "min"),
                                         last=("episode", "max"), collisions=("collisions", "sum"),
                                         goals=("reached_goal", "sum"), steps=("steps", "sum"))
            print(per.to_string())


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m pipeline.records", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("path", help="an .mcap (or .mcap.partial) record file, or a folder of them")
    ap.add_argument("--runs", action="store_true", help="one line per run (episodes, collisions, goals)")
    args = ap.parse_args(argv)
    try:
        code = _list(args)
        sys.stdout.flush()
    except BrokenPipeError:  # the reader went away (``| head``): stop quietly
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # the interpreter's last flush must not fail again
        except (OSError, ValueError):
            pass
        raise SystemExit(141) from None  # 128 + SIGPIPE, as a shell reports a tool stopped by it
    except UserError as exc:
        sys.stdout.flush()
        print(f"error: {exc}", file=sys.stderr, flush=True)
        raise SystemExit(2) from None
    if code:
        raise SystemExit(code)


if __name__ == "__main__":
    main()
