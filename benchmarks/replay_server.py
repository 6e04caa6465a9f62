"""Replay server benchmark: the CPU an idle web viewer's server takes, as the replay stage serves now and as before.

    python -m benchmarks.replay_server [--seconds 10] [--settle 5]

Records a tiny trial with the trials stage (a 5x5 grid cell, 1 run of 2 episodes) and replays its
first episode, then measures the CPU time (user + system, every thread) of each serving process over
``--seconds`` of wall time while no viewer asks for anything, ``--settle`` seconds after it
started:

1. ``python -m pipeline replay ... viewer=web`` as it serves now: the command's own process (waiting
   for the server) and the Rerun server, started empty and sent the recording over gRPC;
2. the Rerun server handed the file, ``rerun --serve-web <file>.rrd`` (as the stage served before):
   in rerun 0.41 a thread of it spins in its log channel's receive loop once the file is read.

Prints a table and writes reports/benchmarks/replay_server.json (percent of one core).
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._output import write_figures

ROOT = Path(__file__).resolve().parents[1]
TRIAL = [
    "maze=5x5",
    "method=fewshot_dss",
    "recogniser=fixed_accuracy",
    "runs=1",
    "episodes=2",
    "progress=false",
]


def cpu_percent(pids: dict[str, int], seconds: float) -> dict[str, float]:
    """Percent of one core each process (name -> pid) used over ``seconds`` of wall time."""
    import psutil

    procs = {name: psutil.Process(pid) for name, pid in pids.items()}
    before = {name: sum(p.cpu_times()[:2]) for name, p in procs.items()}
    time.sleep(seconds)
    return {
        name: round(100 * (sum(p.cpu_times()[:2]) - before[name]) / seconds, 1)
        for name, p in procs.items()
    }


def served_by_the_stage(file: Path, rrd: Path, seconds: float, settle: float) -> dict[str, float]:
    import psutil

    proc = subprocess.Popen(
        [sys.executable, "-m", "pipeline", "replay", f"file={file}", "run=0", "episode=0"]
        + [f"out={rrd}", "viewer=web", "web_port=0", "grpc_port=0"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        for line in proc.stdout:
            if line.startswith("serving "):
                break
        (server,) = psutil.Process(proc.pid).children()
        time.sleep(settle)
        return cpu_percent({"replay command": proc.pid, "rerun server": server.pid}, seconds)
    finally:
        proc.terminate()
        proc.wait(30)


def served_from_the_file(rrd: Path, seconds: float, settle: float) -> dict[str, float]:
    from pipeline.replay.viewer import rerun_command

    ports = []
    for _ in range(2):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            ports.append(s.getsockname()[1])
    proc = subprocess.Popen(
        [*rerun_command(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port"]
        + [str(ports[0]), "--port", str(ports[1]), str(rrd)],
        env={**os.environ, "RUST_LOG": "warn"},
    )
    try:
        time.sleep(settle)
        return cpu_percent({"rerun server": proc.pid}, seconds)
    finally:
        proc.terminate()
        proc.wait(30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="wall seconds measured")
    ap.add_argument("--settle", type=float, default=5.0, help="seconds after the server started")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench" / "fewshot_dss"
        subprocess.run(
            [sys.executable, "-m", "pipeline", "trials", *TRIAL, f"out={out}"],
            cwd=ROOT,
            check=True,
            stdout=subprocess.DEVNULL,
        )
        rrd = Path(tmp) / "replay.rrd"
        now = served_by_the_stage(out / "records.mcap", rrd, args.seconds, args.settle)
        before = served_from_the_file(rrd, args.seconds, args.settle)
    figures = {
        "machine": {
            "cpus": os.cpu_count(),
            "loadavg_at_start": [round(x, 2) for x in os.getloadavg()],
        },
        "seconds": args.seconds,
        "idle_cpu_percent_of_a_core": {"served by the stage": now, "server given the file": before},
    }
    print(f"idle CPU over {args.seconds:g} s (percent of one core)")
    for how, procs in figures["idle_cpu_percent_of_a_core"].items():
        print(f"  {how:<22} " + ", ".join(f"{name} {pct:.1f}%" for name, pct in procs.items()))
    path = write_figures(
        "reports/benchmarks/replay_server.json", figures, "benchmarks.replay_server"
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
