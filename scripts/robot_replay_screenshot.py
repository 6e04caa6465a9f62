"""Regenerate the robot replay's screenshot in the docs (docs/robot3d_replay.png): record a small
``world=robot3d`` few-shot trial (the Relation Network on live pictures; needs ``datasets/images``
and ``datasets/models/relation_net.pt``), build its 3D replay (``python -m pipeline.robot.replay``),
serve it with ``rerun --serve-web`` and photograph the web viewer in headless chromium (as
``scripts/replay_screenshot.py``, whose ``photograph`` this uses).

    python scripts/robot_replay_screenshot.py [--cell datasets/runs/robot3d/fewshot_dss_5x5_robot3d]
        [--run 0] [--episode 0] [--out docs/robot3d_replay.png]
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from replay_screenshot import photograph  # noqa: E402

TRIAL = ["method=fewshot_dss", "world=robot3d", "maze=5x5", "runs=1", "episodes=3", "seed=0",
         "progress=false"]  # fmt: skip
WEB_PORT, GRPC_PORT = 9391, 9392


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--cell", type=Path, help="a robot cell's folder (default: record a small trial)"
    )
    ap.add_argument("--run", type=int, default=0)
    ap.add_argument("--episode", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "robot3d_replay.png")
    ap.add_argument("--settle", type=float, default=20.0)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cell = args.cell.resolve() if args.cell else Path(tmp) / "fewshot_dss"
        if not args.cell:
            run = [sys.executable, "-m", "pipeline"]
            subprocess.run([*run, "trials", *TRIAL, f"out={cell}"], cwd=ROOT, check=True)
        rrd = Path(tmp) / "robot.rrd"
        subprocess.run([sys.executable, "-m", "pipeline.robot.replay", str(cell),
                        "--run", str(args.run), "--episode", str(args.episode), "--out", str(rrd)], cwd=ROOT, check=True)  # fmt: skip
        rerun = str(Path(sys.executable).with_name("rerun"))
        proc = subprocess.Popen([rerun, "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port",
                                 str(WEB_PORT), "--port", str(GRPC_PORT), str(rrd)])  # fmt: skip
        url = (f"http://127.0.0.1:{WEB_PORT}?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{GRPC_PORT}"
               "%2Fproxy")  # fmt: skip
        try:
            photograph(url, args.out, 1600, 1000, args.settle)
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(30)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main(sys.argv[1:])
