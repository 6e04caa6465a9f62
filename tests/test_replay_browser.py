"""The web replay in a real browser: ``python -m pipeline replay ... viewer=web`` serves a recording,
Debian's chromium (driven by Playwright for Python, with the system browser: Playwright's own
browser download is not reachable) opens the address the command printed, and the viewer's active
recording, saved from the page, holds every row of the recording served.

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
import time
from pathlib import Path

import pytest
from synthetic_records import write_synthetic
from test_replay import _rows, web_replay

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
