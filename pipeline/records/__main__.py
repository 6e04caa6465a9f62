"""``python -m pipeline.records <file.mcap | folder> [--runs]``: what a record file (or every record
file under a folder) holds: experiment config, completeness, runs, episodes, collisions, and what
was lost if a file is truncated. The quickest way to find the run and episode to replay."""
from __future__ import annotations

import argparse
import warnings

from .reader import RecordsWarning, read_records


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m pipeline.records", description=__doc__)
    ap.add_argument("path", help="an .mcap record file or a folder of them")
    ap.add_argument("--runs", action="store_true", help="one line per run (episodes, collisions, goals)")
    args = ap.parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordsWarning)
        recs = read_records(args.path, pictures=False)
    for w in caught:
        print(f"warning: {w.message}")
    for name, meta in recs.files.items():
        eps = recs.episodes[recs.episodes.file == name]
        cfg = meta.config or {}
        what = ", ".join(f"{k}={cfg[k]}" for k in ("experiment", "method", "maze", "seed") if k in cfg
                         and not isinstance(cfg[k], dict))
        status = "complete" if meta.complete else "INCOMPLETE"
        print(f"{name}: {status}; {eps.run.nunique()} runs, {len(eps)} episodes, "
              f"{int(eps.collisions.sum())} collisions{'; ' + what if what else ''}")
        if args.runs and len(eps):
            per = eps.groupby("run").agg(episodes=("episode", "size"), first=("episode", "min"),
                                         last=("episode", "max"), collisions=("collisions", "sum"),
                                         goals=("reached_goal", "sum"), steps=("steps", "sum"))
            print(per.to_string())
    print("replay one: python -m pipeline replay file=<file> run=<run> episode=<episode>")


if __name__ == "__main__":
    main()
