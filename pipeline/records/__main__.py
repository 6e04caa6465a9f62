"""``python -m pipeline.records <file.mcap | folder> [--runs]``: one line a record file (config, completeness, runs,
episodes, collisions, what a damaged or cut file lost); a folder's ``*.mcap`` and ``*.mcap.partial`` files (also in
``.staging-*`` folders; killed runs marked PARTIAL), a file that cannot be read named in one line on stderr. Exit
status: 0, all listed; 1, some files could not be read; 2, none could, or no such file or folder; 141, pipe closed.
"""

import argparse
import sys
import warnings
from pathlib import Path

from pipeline.errors import quiet_broken_pipe

from .reader import RecordsError, RecordsWarning, find_record_files, read_records


def main(argv: list[str] | None = None) -> None:
    """List the record files at the path given: per file its warnings and one line (with ``--runs`` one per run)."""
    ap = argparse.ArgumentParser(
        prog="python -m pipeline.records",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument(
        "path", type=Path, help="an .mcap (or .mcap.partial) record file, or a folder of them"
    )
    ap.add_argument(
        "--runs", action="store_true", help="one line per run (episodes, collisions, goals)"
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
    with (
        quiet_broken_pipe()
    ):  # every write to stdout: a reader that goes away (``| head``) ends it quietly
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
            print(
                f"{name}: {meta.status}; {', '.join(counts)}, {int(eps.collisions.sum())} collisions"
                + "".join(f"; {x}" for x in (meta.lost, what) if x)
            )
            if args.runs and len(eps):
                print(
                    eps.groupby("run")
                    .agg(
                        episodes=("episode", "size"),
                        first=("episode", "min"),
                        last=("episode", "max"),
                        collisions=("collisions", "sum"),
                        goals=("reached_goal", "sum"),
                        steps=("steps", "sum"),
                    )
                    .to_string()
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
