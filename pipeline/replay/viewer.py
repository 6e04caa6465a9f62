"""The viewer process of a replay: the Rerun web server, or the desktop viewer, started for one
``.rrd`` recording and stopped with the command that started it (the stage ``replay``).

``serve_web`` starts the Rerun CLI of the rerun-sdk wheel as an empty web server, sends it the
recording over gRPC (:func:`send_recording`: why not the file) and prints the one address that
opens the recording (``http://127.0.0.1:<web_port>?url=rerun+http://127.0.0.1:<grpc_port>/proxy``,
URL-encoded); the bare web port only opens Rerun's welcome page. The server lives and dies with the
command: Ctrl-C or SIGTERM stop it, and so does the command's death on Linux (parent-death signal).
What a viewer needs is checked before any work: the ports and the bind address
(:func:`web_address`), a display (:func:`check_display`).
"""

from __future__ import annotations

import ctypes
import importlib.util
import ipaddress
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

from pipeline.config.fields import refuse
from pipeline.errors import Interrupted


@dataclass(frozen=True)
class WebAddress:
    """Where the web viewer listens and the address a browser opens."""

    bind: str
    """The IP address the server listens on (``0.0.0.0``: every interface)."""
    host: str
    """The host a browser asks for (``127.0.0.1`` for an unspecified ``bind``; IPv6 in brackets)."""
    web_port: int
    """The viewer's HTTP port."""
    grpc_port: int
    """The port of the gRPC proxy that serves the recording."""

    @property
    def grpc(self) -> str:
        """The gRPC proxy that serves the recording."""
        return f"rerun+http://{self.host}:{self.grpc_port}/proxy"

    @property
    def url(self) -> str:
        """The page that opens the recording: the web port, told where the gRPC proxy is."""
        return f"http://{self.host}:{self.web_port}?url={quote(self.grpc, safe='')}"


def web_address(bind: str, allow_remote: bool, web_port: int, grpc_port: int) -> WebAddress:
    """Check ``bind`` and both ports: a non-loopback bind needs ``allow_remote`` (and warns), a busy
    port is a :class:`~pipeline.errors.ConfigError` naming its key, port 0 becomes a free port (the
    two differ)."""
    ip = bind_address(bind, allow_remote)
    if web_port and web_port == grpc_port:
        refuse(("web_port", "grpc_port"), f"both are {web_port}; give two ports")
    with (
        _bound(ip, web_port, "web_port") as web,
        _bound(ip, grpc_port, "grpc_port") as grpc,
    ):
        ports = web.getsockname()[1], grpc.getsockname()[1]
    host = "127.0.0.1" if ip.is_unspecified else f"[{ip}]" if ip.version == 6 else str(ip)
    return WebAddress(str(ip), host, *ports)


def bind_address(bind: str, allow_remote: bool) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """``bind`` as an IP address; one off the loopback only with ``allow_remote`` (and a warning)."""
    try:
        ip = ipaddress.ip_address("127.0.0.1" if bind == "localhost" else bind)
    except ValueError:
        refuse("bind", f"not an IP address: {bind!r} (127.0.0.1 keeps it local)")
    if ip.is_loopback:
        return ip
    if not allow_remote:
        refuse(
            "bind",
            f"{bind} is reachable from other machines; keep 127.0.0.1, "
            "or add allow_remote=true to serve the recording to the network",
        )
    print(
        f"warning: bind={bind}: the viewer and the recording are served to every machine that can reach "
        "this one, without authentication (allow_remote=true)",
        file=sys.stderr,
        flush=True,
    )
    return ip


@contextmanager
def _bound(ip, port: int, key: str) -> Iterator[socket.socket]:
    """A socket bound to ``(ip, port)`` (with the server's own ``SO_REUSEADDR``): the port is free;
    port 0 picks one."""
    with socket.socket(
        socket.AF_INET6 if ip.version == 6 else socket.AF_INET, socket.SOCK_STREAM
    ) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((str(ip), port))
        except OSError as exc:
            hint = f" (another viewer? {key}=0 picks a free port)" if port else ""
            refuse(key, f"cannot listen on {ip} port {port}: {exc.strerror}{hint}")
        yield sock


def server_command(web: WebAddress) -> list[str]:
    """The Rerun web server at ``web``, started empty (it is sent the recording)."""
    return rerun_command() + [
        "--serve-web",
        "--bind",
        web.bind,
        "--web-viewer-port",
        str(web.web_port),
        "--port",
        str(web.grpc_port),
    ]


def serve_web(rrd: str | Path, web: WebAddress) -> None:
    """Serve ``rrd`` at ``web`` until Ctrl-C, SIGTERM (through the stage's handler) or the server's
    end; the server never outlives this call. It starts empty and gets the recording over gRPC
    (:func:`send_recording`), so it sleeps while no viewer asks for anything."""
    cmd = server_command(web)
    # quieted: Rerun's own log repeats the address without the recording
    env = {"RUST_LOG": "warn", **os.environ}
    # preexec_fn: this stage starts no threads, so the fork-unsafety it warns of does not apply
    proc = subprocess.Popen(cmd, env=env, start_new_session=True, preexec_fn=_die_with_parent)  # noqa: PLW1509
    try:
        wait_listening(proc, web)
        send_recording(rrd, web.grpc)
        print(f"serving {rrd} at {web.url}  (Ctrl-C to stop)", flush=True)
        if proc.wait():
            raise SystemExit(f"error: the Rerun viewer exited with status {proc.returncode}")
    except KeyboardInterrupt:
        print(f"viewer stopped; the recording stays at {rrd}", file=sys.stderr, flush=True)
    except Interrupted as exc:  # SIGTERM (the stage's handler): the same words, exit 143
        raise Interrupted(exc.code, f"viewer stopped; the recording stays at {rrd}") from None
    finally:
        stop_server(proc)


def send_recording(rrd: str | Path, grpc: str) -> None:
    """Send the recording and blueprint of ``rrd`` to the Rerun server at ``grpc``, which keeps them
    for every viewer that connects, under the file's own application and recording ids (a server
    handed the file instead, ``rerun --serve-web file.rrd``, spins a core in rerun 0.41 for as long
    as it runs, once the file is read: docs/replay.md)."""
    import rerun as rr
    import rerun.chunk

    store = rerun.chunk.RrdReader(rrd).recordings()[0]
    rec = rr.RecordingStream(
        store.application_id, recording_id=store.recording_id, send_properties=False
    )
    rec.connect_grpc(grpc)
    rec.log_file_from_path(rrd)
    rec.flush()  # waits for the file's importer and the network
    rec.disconnect()


#: Seconds to wait for the Rerun server to listen on both ports.
START_TIMEOUT = 30.0


def wait_listening(proc: subprocess.Popen, web: WebAddress) -> None:
    """Return once both ports accept connections; a server that ends first is a port problem."""
    deadline = time.monotonic() + START_TIMEOUT
    while not all(_accepts(web.host.strip("[]"), port) for port in (web.grpc_port, web.web_port)):
        if proc.poll() is not None:
            refuse(
                ("web_port", "grpc_port"),
                f"the Rerun viewer ended at start (status {proc.returncode}; its log is above)",
            )
        if time.monotonic() > deadline:
            raise SystemExit(
                f"error: the Rerun viewer did not listen on {web.host} in {START_TIMEOUT:.0f} s"
            )
        time.sleep(0.1)


def _accepts(host: str, port: int) -> bool:
    try:
        socket.create_connection((host, port), timeout=0.5).close()
    except OSError:
        return False
    return True


#: Seconds to wait for the Rerun server to end once told to stop.
STOP_TIMEOUT = 5.0


def stop_server(proc: subprocess.Popen) -> None:
    """End the server's process group: SIGTERM, then SIGKILL after :data:`STOP_TIMEOUT`."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            break
        try:
            os.killpg(proc.pid, sig)
            proc.wait(STOP_TIMEOUT)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass


def _die_with_parent() -> None:
    """In the child (Linux): SIGTERM when the command dies, even by SIGKILL (``prctl(PR_SET_PDEATHSIG)``)."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)


def rerun_command() -> list[str]:
    """The Rerun CLI binary of the rerun-sdk wheel (not its Python wrapper, so one process to stop)."""
    spec = importlib.util.find_spec("rerun_cli")
    exe = Path(spec.origin).with_name("rerun") if spec and spec.origin else None
    return [str(exe)] if exe and exe.exists() else [sys.executable, "-m", "rerun_cli"]


def check_display(viewer: str) -> None:
    """``viewer=native`` on Linux without a display (neither ``DISPLAY`` nor ``WAYLAND_DISPLAY``):
    a :class:`~pipeline.errors.ConfigError` naming the key and the alternatives (the viewer would fail to open a
    window after the replay's work, while the command exits 0)."""
    if viewer != "native" or not sys.platform.startswith("linux"):
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        refuse(
            "viewer",
            "viewer=native needs a display and there is none (DISPLAY and "
            "WAYLAND_DISPLAY are unset); use viewer=web to serve the replay to a browser, or "
            "viewer=none to save the .rrd only (then open it with rerun <file>.rrd where there is a "
            "display)",
        )


def open_viewer(rrd: str | Path, viewer: str) -> subprocess.Popen | None:
    """``"native"``: spawn the desktop viewer (needs a display); ``"none"``: nothing (``"web"``: see
    :func:`serve_web`)."""
    if viewer == "native":
        return subprocess.Popen(rerun_command() + [str(rrd)])
    if viewer != "none":
        raise ValueError(f"viewer must be 'none' or 'native' here, got {viewer!r}")
    return None
