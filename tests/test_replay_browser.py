"""The web replay in a real browser: ``python -m pipeline replay ... viewer=web`` serves a recording,
Debian's chromium (driven by Playwright for Python, with the system browser: Playwright's own
browser download is not reachable) opens the address the command printed, and the viewer's active
recording, saved from the page, holds every row of the recording served. A robot cell's replay
opens without a view's error badge (Rerun's red "!" in a view's title, e.g. "2D visualizers require
a pinhole ancestor"), looked for in a screenshot: the same check finds the badge on a recording
made to have one.

The Rerun web viewer draws everything on a canvas (no DOM text), so the page is asked through the
handle its ``index.html`` publishes (``window._handle.save_recording()``: the active recording as
RRD bytes; on the welcome page it throws "No active recording"). The WASM bundle takes 20-60 s to
load on 2 cores with software WebGL. Skipped without playwright (the ``test`` extra) or chromium
(``apt-get install chromium``; ``scripts/setup.sh`` installs it when run as root).
"""

from __future__ import annotations

import base64
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from synthetic_records import write_synthetic
from test_replay import _rows, web_replay
from test_replay_robot import cell  # noqa: F401 (a fixture)

pytestmark = (
    pytest.mark.slow
)  # 50 s, most of it the viewer's WASM loading: `make test-slow` runs it

CHROMIUM = Path(os.environ.get("CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
LOAD_TIMEOUT = 150.0  # seconds for the viewer to show the whole recording
#: The colour of Rerun 0.41's error badge on a view's title bar (a disc with "!", about 130 pixels
#: at 1600 x 1000), and how near a pixel must be to count; nothing the replays draw comes this near.
BADGE, BADGE_TOLERANCE, BADGE_PIXELS = (236, 0, 79), 24, 50

#: The page's active recording as base64 RRD; null before the viewer has started, "ERR ..." without one.
SAVE_RECORDING = """() => {
  const handle = window._handle;
  if (!handle) return null;
  try {
    const bytes = handle.save_recording();
    let text = "";
    for (let i = 0; i < bytes.length; i += 8192) text += String.fromCharCode(...bytes.subarray(i, i + 8192));
    return btoa(text);
  } catch (e) {
    return "ERR " + e;
  }
}"""


@pytest.fixture(scope="module")
def chromium():
    """A headless chromium of the system, through Playwright."""
    sync_api = pytest.importorskip(
        "playwright.sync_api",
        reason="playwright is not installed (the 'test' extra)",
        exc_type=ImportError,
    )
    if not os.access(CHROMIUM, os.X_OK):
        pytest.skip(
            f"no chromium at {CHROMIUM} (apt-get install chromium; scripts/setup.sh does it as root)"
        )
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS
        )
        try:
            yield browser
        finally:
            browser.close()


def _viewer_recording(page, expected: dict[str, int], out: Path) -> dict[str, int] | str | None:
    """Poll the page until its active recording has ``expected`` rows or :data:`LOAD_TIMEOUT` passes;
    the last rows seen (or the viewer's answer: None before it started, "ERR ..." without a recording)."""
    deadline, seen = time.monotonic() + LOAD_TIMEOUT, None
    while time.monotonic() < deadline:
        seen = page.evaluate(SAVE_RECORDING)
        if seen and not seen.startswith("ERR"):
            out.write_bytes(base64.b64decode(seen))
            try:
                seen = _rows(out)
            except ValueError as exc:  # saved before its recording store arrived (a busy machine)
                seen = f"not yet: {exc}"
            if seen == expected:
                break
        time.sleep(2)
    return seen


def _started(page, settle: float = 0) -> str | None:
    """The page's answer to :data:`SAVE_RECORDING` once the viewer has started (then ``settle`` s more)."""
    deadline = time.monotonic() + LOAD_TIMEOUT
    while page.evaluate(SAVE_RECORDING) is None and time.monotonic() < deadline:
        time.sleep(1)
    time.sleep(settle)
    return page.evaluate(SAVE_RECORDING)


def test_the_printed_address_opens_the_recording_in_chromium(chromium, tmp_path):
    write_synthetic(tmp_path / "r.mcap", runs=1, episodes_per_run=2, seed=3)
    served = tmp_path / "served.rrd"
    with web_replay(tmp_path / "r.mcap", served) as (_, url, _children):
        expected = _rows(served)
        page = chromium.new_page(viewport={"width": 1280, "height": 800})
        start = time.monotonic()
        page.goto(url, wait_until="commit")
        seen = _viewer_recording(page, expected, tmp_path / "from_browser.rrd")
        page.screenshot(path=tmp_path / "viewer.png")
        print(
            f"the viewer showed the recording after {time.monotonic() - start:.0f} s ({tmp_path / 'viewer.png'})"
        )
        assert seen == expected, f"the viewer's active recording: {seen!r}"
        assert {
            "/maze/robot",
            "/recognition/scores/chair",
            "/support/note",
            "/__properties",
            "/events",
        } <= seen.keys()

        start = time.monotonic()  # the bare web port: Rerun's welcome page, without the recording
        welcome = chromium.new_page(viewport={"width": 1280, "height": 800})
        welcome.goto(url.split("?")[0], wait_until="commit")
        assert _started(welcome, settle=3) == "ERR No active recording to save"
        print(f"the welcome page started after {time.monotonic() - start:.0f} s")


def badge_pixels(png: Path) -> int:
    """How many pixels of the screenshot ``png`` have the error badge's colour."""
    from PIL import Image

    with Image.open(png) as im:
        rgb = np.asarray(im.convert("RGB"), np.int16)
    return int((np.abs(rgb - np.array(BADGE)).max(axis=-1) <= BADGE_TOLERANCE).sum())


def _screenshot_when_shown(chromium, url: str, expected: dict[str, int], tmp_path: Path, name: str):
    """Open ``url``, wait until the viewer holds the ``expected`` rows, let it draw, screenshot."""
    page = chromium.new_page(viewport={"width": 1600, "height": 1000})
    page.goto(url, wait_until="commit")
    seen = _viewer_recording(page, expected, tmp_path / f"{name}.rrd")
    assert seen == expected, f"the viewer's active recording: {seen!r}"
    time.sleep(5)  # a few frames: the views and their badges are drawn
    png = tmp_path / f"{name}.png"
    page.screenshot(path=png)
    page.close()
    return png


def test_a_robot_replay_opens_without_an_error_badge(chromium, cell, tmp_path):  # noqa: F811
    served = tmp_path / "robot.rrd"
    with web_replay(cell, served, episode=0) as (_, url, _children):
        png = _screenshot_when_shown(chromium, url, _rows(served), tmp_path, "robot")
    print(f"the robot's replay in chromium: {png}")
    assert badge_pixels(png) == 0


def test_the_badge_check_finds_the_badge_of_2d_content_in_a_3d_view(chromium, tmp_path):
    """The check above can fail: points in 2D inside the 3D space, without a pinhole, shown in a
    3D view, give the badge (served as the replay serves: an empty server sent the recording)."""
    import rerun as rr
    import rerun.blueprint as rrb

    from pipeline.replay.viewer import (
        WebAddress,
        send_recording,
        server_command,
        stop_server,
        wait_listening,
    )

    rrd = tmp_path / "badge.rrd"
    rec = rr.RecordingStream("badge_check", recording_id="badge")
    stream = rec.binary_stream()
    rec.send_blueprint(rrb.Blueprint(rrb.Spatial3DView(origin="/", name="3D")))
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log("box", rr.Boxes3D(centers=[[0, 0, 0]], half_sizes=[[1, 1, 1]]), static=True)
    rec.log("flat", rr.Points2D([[0, 0], [1, 1]], radii=0.2), static=True)  # no pinhole above it
    rrd.write_bytes(stream.read(flush=True) or b"")
    rec.disconnect()
    web = WebAddress("127.0.0.1", "127.0.0.1", *_free_ports(2))
    server = subprocess.Popen(server_command(web), env={**os.environ, "RUST_LOG": "warn"})
    try:
        wait_listening(server, web)
        send_recording(rrd, web.grpc)
        png = _screenshot_when_shown(chromium, web.url, _rows(rrd), tmp_path, "badge")
    finally:
        stop_server(server)
    print(f"a recording with the badge in chromium: {png}")
    assert badge_pixels(png) >= BADGE_PIXELS


def _free_ports(n: int) -> list[int]:
    import socket

    socks = [socket.socket() for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()
