"""Regenerate the viewer's screenshot in the docs (docs/replay.png): record a small few-shot trial
with the trials stage (the Relation Network, so the file holds the support pictures; needs
``datasets/images`` and ``datasets/models/relation_net.pt``, i.e. ``make repro``), replay an episode
with ``python -m pipeline replay ... viewer=web`` and photograph the web viewer in headless
chromium (Playwright with the system browser, as ``tests/test_replay_browser.py``).

    python scripts/replay_screenshot.py                                   # -> docs/replay.png
    python scripts/replay_screenshot.py --file datasets/runs/fig8/fewshot_dss/records.mcap --run 3 --episode 120
    python scripts/replay_screenshot.py recogniser.images_dir=/elsewhere/images   # trials overrides
    python scripts/replay_screenshot.py --out docs/robot3d_replay.png --settle 20 world=robot3d

A robot cell (``world=robot3d``) replays in 3D. The viewer's WASM takes 20-60 s to start with
software WebGL on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = os.environ.get("CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: The trial photographed by default: episode 0 of one run substitutes four pictures into the support set.
TRIAL = [
    "method=fewshot_dss",
    "maze=5x5",
    "runs=1",
    "episodes=20",
    "seed=0",
    "progress=false",
    "threads=1",
]
#: True once the page's viewer holds a recording (``window._handle``: see tests/test_replay_browser.py).
HAS_RECORDING = """() => { try { return !!(window._handle && window._handle.save_recording().length); }
                           catch (e) { return false; } }"""


def record_trial(folder: Path, overrides: list[str]) -> Path:
    """A small recorded few-shot trial in ``folder/demo/fewshot_dss`` (so the replay is named after it)."""
    out = folder / "demo" / "fewshot_dss"
    subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", *TRIAL, f"out={out}", *overrides],
        cwd=ROOT,
        check=True,
    )
    return out / "records.mcap"


def serve(file: Path, run: int, episode: int, rrd: Path) -> tuple[subprocess.Popen, str]:
    """``python -m pipeline replay ... viewer=web`` on free ports, and the address it prints."""
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={file}",
            f"run={run}",
            f"episode={episode}",
            f"out={rrd}",
            "viewer=web",
            "web_port=0",
            "grpc_port=0",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    for line in proc.stdout:
        if line.startswith("serving "):
            return proc, re.search(r"http://\S+", line).group(0)
    raise SystemExit(f"error: the replay ended ({proc.wait()}) before serving")


def photograph(
    url: str, png: Path, width: int, height: int, settle: float, timeout: float = 180.0
) -> None:
    """Open ``url`` in headless chromium, wait until the viewer holds the recording, then ``settle``
    seconds for it to draw, and save the page as ``png``."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": width, "height": height})
        page.goto(url, wait_until="commit")
        deadline = time.monotonic() + timeout
        while not page.evaluate(HAS_RECORDING):
            if time.monotonic() > deadline:
                raise SystemExit(
                    f"error: the viewer did not show the recording within {timeout:.0f} s"
                )
            time.sleep(2)
        time.sleep(settle)
        page.screenshot(path=png)
        browser.close()


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--file", type=Path, help="record file to replay (default: record a small trial first)"
    )
    ap.add_argument("--run", type=int, default=0)
    ap.add_argument("--episode", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "replay.png")
    ap.add_argument("--size", default="1600x1000", help="browser viewport, WIDTHxHEIGHT")
    ap.add_argument("--settle", type=float, default=15.0, help="seconds to let the viewer draw")
    ap.add_argument("trial", nargs="*", help="more overrides of the trial recorded without --file")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        file = args.file.resolve() if args.file else record_trial(Path(tmp), args.trial)
        proc, url = serve(file, args.run, args.episode, Path(tmp) / "replay.rrd")
        try:
            photograph(url, args.out, width, height, args.settle)
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(30)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main(sys.argv[1:])
