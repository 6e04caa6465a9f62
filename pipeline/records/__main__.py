"""``python -m pipeline.records``: what record files hold, one line a file or a table of its runs.

``python -m pipeline.records <file.mcap | folder> [--runs]`` (installed: ``safenav records``): one
line a record file (config, completeness, runs, episodes, collisions, the episodes that hold
recognitions and substitutions, what a damaged or cut file lost); a folder's ``*.mcap`` and
``*.mcap.partial`` files (also in ``.staging-*`` folders; killed runs marked PARTIAL), an
unreadable file named in one line on stderr. ``--runs``: a table, one row per run. Exit status: 0,
all listed; 1, some files could not be read; 2, none could, or no such file or folder; 141, pipe
closed.
"""

import argparse
import sys
import warnings
from pathlib import Path

from pipeline.errors import quiet_broken_pipe

from .loss import describe
from .reader import RecordsError, RecordsWarning, find_record_files, read_records


def _episodes_with(frame) -> list[tuple[int, int, int]]:
    """The (run, first, last) ranges of the episodes with a row in ``frame``."""
    pairs = sorted(set(zip(frame.run.tolist(), frame.episode.tolist())))
    return [(r, e, e) for r, e in pairs]


def _line(name: str, recs, meta) -> str:
    eps, cfg = recs.episodes, meta.config or {}
    counts = [
        f"{n} {unit}" if exp in (None, n) else f"{n} of {exp} {unit}"
        for n, exp, unit in (
            (eps.run.nunique(), meta.expected_runs, "runs"),
            (len(eps), meta.expected_episodes, "episodes"),
        )
    ]
    what = ", ".join(
        f"{k}={cfg[k]}"
        for k in ("experiment", "method", "maze", "seed")
        if not isinstance(cfg.get(k, {}), dict)
    )
    seen = [
        f"{label} in {describe(_episodes_with(frame), None)}"
        for label, frame in (
            ("recognitions", recs.recognitions),
            ("substitutions", recs.substitutions[recs.substitutions.picture >= 0]),
        )
        if len(frame)
    ]
    tail = "".join(f"; {x}" for x in (meta.lost, *seen, what) if x)
    return (
        f"{name}: {meta.status}; {', '.join(counts)}, {int(eps.collisions.sum())} collisions{tail}"
    )


def main(argv: list[str] | None = None, prog: str = "python -m pipeline.records") -> None:
    """List the record files at the path given: per file its warnings and one line. ``prog``: the
    command's name in its help (``safenav records`` when run by :mod:`pipeline.cli`)."""
    ap = argparse.ArgumentParser(
        prog=prog,
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument(
        "path", type=Path, help="an .mcap (or .mcap.partial) record file, or a folder of them"
    )
    ap.add_argument(
        "--runs",
        action="store_true",
        help="one line per run (episodes, collisions, goals, recognitions)",
    )
    args, bad = ap.parse_args(argv), 0
    path = args.path
    files = (
        find_record_files(path, every_partial=True)
        if path.is_dir()
        else [path]
        if path.exists()
        else []
    )
    with quiet_broken_pipe():  # a reader that goes away (``| head``) ends it quietly
        for f in files:
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", RecordsWarning)
                    recs = read_records(f, pictures=False)
                ((name, meta),) = recs.files.items()
                if meta.unusable:  # our magic bytes, then nothing readable: a cut copy
                    raise RecordsError(meta.unusable)
            except RecordsError as e:  # named in one line; the other files are still listed
                print(f"error: {e}", file=sys.stderr, flush=True)
                bad += 1
                continue
            print(
                "".join(
                    f"warning: {w.message}\n"
                    for w in caught
                    if issubclass(w.category, RecordsWarning)
                ),
                end="",
            )
            print(_line(name, recs, meta))
            if args.runs and len(recs.episodes):
                per_run = recs.episodes.groupby("run").agg(
                    episodes=("episode", "size"),
                    first=("episode", "min"),
                    last=("episode", "max"),
                    collisions=("collisions", "sum"),
                    goals=("reached_goal", "sum"),
                    steps=("steps", "sum"),
                    recognitions=("n_recognitions", "sum"),
                )
                subs = recs.substitutions[recs.substitutions.picture >= 0].groupby("run").size()
                print(
                    per_run.assign(
                        substitutions=subs.reindex(per_run.index, fill_value=0)
                    ).to_string()
                )
        if bad < len(files):
            print(
                "replay one: python -m pipeline replay file=<file> run=<run> episode=<episode>",
                flush=True,
            )
        elif len(files) != 1:  # nothing listed, and no file's error said why
            why = (
                f"none of its {bad} record files could be read"
                if files
                else "no such record file or folder"
                if not path.is_dir()
                else "no record files (*.mcap, *.mcap.partial) under this folder"
            )
            print(f"error: {path}: {why}", file=sys.stderr, flush=True)
    if bad or not files:
        raise SystemExit(2 if bad == len(files) else 1)


if __name__ == "__main__":
    main()
