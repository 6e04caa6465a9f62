"""Fresh-clone benchmark: README's two commands from a clean clone, timed step by step.

    python -m benchmarks.fresh_clone [--skip-test] [--keep]

Clones this repository's ``HEAD`` (``git clone``: committed files only) into a temporary folder
and runs there, as a new user would:

1. ``make setup``: ``scripts/setup.sh``, the ``.venv`` from ``requirements.lock``;
2. ``make repro``: ``dvc repro`` at the paper's scale (set-up already done), each stage's wall
   time from the moment DVC announces it (``Running stage '<name>'``) to the next;
3. ``make test`` (unless ``--skip-test``);

then ``git status --porcelain`` in the clone (README promises it stays empty). Writes
reports/benchmarks/fresh_clone.json and prints a table. Takes what the commands take: about 15-20
minutes on 2 cores, more when other work shares them (the file records the load average before
and after). ``--keep`` leaves the clone in place and prints where it is.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._output import write_figures

ROOT = Path(__file__).resolve().parents[1]
STAGE_LINE = re.compile(r"^Running stage '([^']+)'")


def timed(cmd: list[str], cwd: Path, env: dict, log: Path) -> tuple[float, dict[str, float], int]:
    """Run ``cmd``, its output to ``log``; (wall seconds, seconds per DVC stage in the order run,
    exit code). A stage's time runs from its ``Running stage`` line to the next one or the end."""
    stages: dict[str, float] = {}
    start = current_start = time.monotonic()
    current = None
    with log.open("w") as out:
        proc = subprocess.Popen(
            cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        for line in proc.stdout:
            out.write(line)
            found = STAGE_LINE.match(line)
            if found:
                now = time.monotonic()
                if current:
                    stages[current] = round(now - current_start, 1)
                current, current_start = found[1], now
        code = proc.wait()
    end = time.monotonic()
    if current:
        stages[current] = round(end - current_start, 1)
    return round(end - start, 1), stages, code


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-test", action="store_true", help="time set-up and repro only")
    parser.add_argument("--keep", action="store_true", help="leave the clone in place")
    args = parser.parse_args(argv)
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    work = Path(tempfile.mkdtemp(prefix="fresh-clone-"))
    clone = work / "repo"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("VIRTUAL_ENV", "PYTHON"))}
    env["PATH"] = os.pathsep.join(
        p for p in env.get("PATH", "").split(os.pathsep) if not p.startswith(str(ROOT))
    )
    env.setdefault("MUJOCO_GL", "egl")
    figures: dict = {"commit": head, "cores": os.cpu_count(), "load_before": os.getloadavg()[0]}
    steps = [("setup", ["make", "setup"]), ("repro", ["make", "repro"])]
    if not args.skip_test:
        steps.append(("test", ["make", "test"]))
    for name, cmd in steps:
        print(f"[fresh_clone] {' '.join(cmd)} ...", file=sys.stderr, flush=True)
        seconds, stages, code = timed(cmd, clone, env, work / f"{name}.log")
        figures[f"{name}_seconds"] = seconds
        if stages:
            figures[f"{name}_stages_seconds"] = stages
        if code != 0:
            figures[f"{name}_exit_code"] = code
            print(f"[fresh_clone] {name} failed (exit {code}); log: {work / f'{name}.log'}")
            break
    status = subprocess.run(
        ["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True
    ).stdout
    figures["git_status_after"] = status.splitlines()
    figures["load_after"] = os.getloadavg()[0]
    path = write_figures(ROOT / "reports/benchmarks/fresh_clone.json", figures, __spec__.name)
    for key, value in figures.items():
        if key.endswith("_seconds") and not isinstance(value, dict):
            print(f"{key.removesuffix('_seconds'):<8} {value / 60:6.1f} min")
    for stage, seconds in figures.get("repro_stages_seconds", {}).items():
        print(f"  {stage:<28} {seconds:7.1f} s")
    print(f"git status after: {'empty' if not status else status}")
    print(f"wrote {path}")
    failed = any(k.endswith("_exit_code") for k in figures)
    if args.keep or failed:
        print(f"the clone and its logs: {work}")
    else:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
