"""How the replay stage hands its recording to a viewer (pipeline.replay.viewer): ``viewer=native``
refused without a display, before any work; ``viewer=web``'s server started empty and sent the
recording over gRPC (given the file, rerun 0.41's server keeps a core busy while it runs)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import warnings

import pytest
from entry import cli
from synthetic_records import write_synthetic
from test_replay import _rows

from pipeline.errors import ConfigError
from pipeline.replay import build_replay
from pipeline.replay.viewer import check_display, rerun_command, send_recording

NO_DISPLAY = (
    "error: config key 'viewer': viewer=native needs a display and there is none (DISPLAY and "
    "WAYLAND_DISPLAY are unset); use viewer=web to serve the replay to a browser, or viewer=none to "
    "save the .rrd only (then open it with rerun <file>.rrd where there is a display)"
)


@pytest.fixture
def no_display(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")  # the check is Linux's (X11 or Wayland)


def test_viewer_native_without_a_display_is_one_error_line_before_any_work(no_display, tmp_path):
    write_synthetic(tmp_path / "r.mcap", runs=1, episodes_per_run=2, seed=3)
    out = tmp_path / "n.rrd"
    res = cli(
        "replay", f"file={tmp_path / 'r.mcap'}", "run=0", "episode=1", "viewer=native", f"out={out}"
    )
    assert res.returncode == 2
    assert res.stderr.splitlines() == [NO_DISPLAY]
    assert res.stdout == "" and not out.exists()  # nothing read, nothing written


@pytest.mark.parametrize(
    "viewer, env, refused",
    [
        ("native", {}, True),
        ("native", {"DISPLAY": ":0"}, False),
        ("native", {"WAYLAND_DISPLAY": "wayland-0"}, False),
        ("web", {}, False),
        ("none", {}, False),
    ],
)
def test_only_the_native_viewer_needs_a_display(no_display, monkeypatch, viewer, env, refused):
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    if refused:
        with pytest.raises(
            ConfigError, match="^config key 'viewer': viewer=native needs a display"
        ):
            check_display(viewer)
    else:
        check_display(viewer)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _saved_rows(path) -> dict | None:
    """The rows of a file a server is still writing (None until it reads)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the server's file has no footer (rerun's own warning)
        try:
            return _rows(path)
        except (OSError, ValueError):
            return None


def _saving_server(saved, attempts: int = 3) -> tuple[subprocess.Popen, int]:
    """A Rerun gRPC server on a free loopback port, saving what it receives to ``saved``, once it
    accepts connections. A port another process took between the choice and the bind (the tests
    run two workers, each starting servers) ends that server at once: another port is tried."""
    for _ in range(attempts):
        port = _free_port()
        server = subprocess.Popen(
            [
                *rerun_command(),
                *("--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)),
                *("--save", str(saved)),
            ],
            env={**os.environ, "RUST_LOG": "warn"},
        )
        deadline = time.monotonic() + 30
        while server.poll() is None and time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                return server, port
            except OSError:
                time.sleep(0.1)
        server.terminate()
        server.wait(30)
    raise AssertionError(f"no Rerun server accepted connections in {attempts} attempts")


def test_the_server_started_empty_gets_the_whole_recording_over_grpc(tmp_path):
    """What the web viewer's server holds after :func:`send_recording`: every row of the ``.rrd``,
    under the file's own application and recording ids (a Rerun server saving what it receives)."""
    import rerun.chunk

    write_synthetic(tmp_path / "r.mcap", runs=1, episodes_per_run=2, seed=3)
    rrd = build_replay(tmp_path / "r.mcap", 0, 1, out=tmp_path / "r.rrd")
    saved = tmp_path / "saved.rrd"
    server, port = _saving_server(saved)
    try:
        deadline = time.monotonic() + 30
        send_recording(rrd, f"rerun+http://127.0.0.1:{port}/proxy")
        expected = _rows(rrd)
        while time.monotonic() < deadline + 30 and _saved_rows(saved) != expected:
            time.sleep(0.5)  # the server writes what it got as it likes
    finally:
        server.terminate()
        server.wait(30)
    assert _saved_rows(saved) == _rows(rrd)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the server's file has no footer (rerun's own warning)
        stores = rerun.chunk.RrdReader(saved).recordings()
    ids = [(s.application_id, s.recording_id) for s in stores]
    own = rerun.chunk.RrdReader(rrd).recordings()
    assert ids == [(s.application_id, s.recording_id) for s in own]  # no recording of its own
