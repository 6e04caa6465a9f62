"""Stage ``replay``: a Rerun recording of one recorded episode (or run) from an MCAP record file.

    python -m pipeline replay file=<file.mcap> run=3 episode=120 [whole_run=true] [viewer=web|native]

The file may also be given positionally (``python -m pipeline replay <file.mcap> run=3 ...``).
Logic in :mod:`pipeline.records.replay`; this is the thin entry point (conf/replay.yaml) and
starts the viewer.
"""
from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

from pipeline.errors import ConfigError
from pipeline.stages._common import stage_main
from pipeline.stages._schema import ReplayConfig


def run(cfg: ReplayConfig, overrides: list[str] = ()) -> Path:
    from pipeline.records import RecordsWarning
    from pipeline.records.replay import ReplayError, build_replay

    path = Path(cfg.file).resolve()
    if not path.is_file():
        raise ConfigError(f"config key 'file': no such record file: {path}")
    stem = path.name.removesuffix(".partial").removesuffix(".mcap")
    out = cfg.out or f"replays/{stem}-run{cfg.run}-" + ("all" if cfg.whole_run else f"ep{cfg.episode}") + ".rrd"
    out = Path(out).resolve()
    if out.suffix != ".rrd":
        raise ConfigError(f"config key 'out': must end in .rrd, got {out}")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RecordsWarning)
            rrd = build_replay(path, cfg.run, None if cfg.whole_run else cfg.episode, out=out,
                               whole_run=cfg.whole_run)
    except ReplayError as exc:
        keys = "key 'file'" if exc.key == "file" else "keys 'run'/'episode'"
        raise ConfigError(f"config {keys}: {exc}") from None
    for w in caught:  # a damaged or truncated record file: one line saying what it lost
        if issubclass(w.category, RecordsWarning):
            print(f"warning: {w.message}", file=sys.stderr, flush=True)
    print(f"open it with: rerun {rrd}", flush=True)
    open_viewer(rrd, cfg.viewer, bind=cfg.bind, web_port=cfg.web_port, grpc_port=cfg.grpc_port)
    return rrd


def open_viewer(rrd: str | Path, viewer: str, *, bind: str = "127.0.0.1", web_port: int = 9090,
                grpc_port: int = 9876) -> subprocess.Popen | None:
    """``"web"``: serve ``rrd`` to a web viewer on ``bind`` (never all interfaces unless asked) and
    block until Ctrl-C; ``"native"``: spawn the desktop viewer (needs a display); ``"none"``: nothing.
    The viewer is the Rerun CLI of the rerun-sdk wheel, beside this interpreter."""
    exe = Path(sys.executable).with_name("rerun")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "rerun_cli"]
    if viewer == "native":
        return subprocess.Popen(cmd + [str(rrd)])
    if viewer == "web":
        print(f"serving {rrd} at http://{bind}:{web_port} (Ctrl-C to stop)", flush=True)
        try:
            subprocess.run(cmd + ["--serve-web", "--bind", bind, "--web-viewer-port", str(web_port),
                                  "--port", str(grpc_port), str(rrd)], check=False)
        except KeyboardInterrupt:
            pass
    elif viewer != "none":
        raise ValueError(f"viewer must be 'none', 'web' or 'native', got {viewer!r}")
    return None


def main() -> None:
    """Accept the record file as a positional argument too (``replay <file.mcap> run=3``)."""
    args = sys.argv[1:]
    for i, a in enumerate(args):
        if "=" not in a and not a.startswith("-") and (a.endswith(".mcap") or a.endswith(".mcap.partial")):
            args[i] = "file=" + "'" + a.replace("'", "\\'") + "'"
    stage_main("replay", run, args)


if __name__ == "__main__":
    main()
