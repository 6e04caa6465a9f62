"""Stage ``replay``: a Rerun recording of one recorded episode (or run) from an MCAP record file.

    python -m pipeline replay file=<file.mcap> run=3 episode=120 [whole_run=true] [viewer=web|native]

The file may also be given positionally (``python -m pipeline replay <file.mcap> run=3 ...``).
Logic in :mod:`pipeline.records.replay`; this is the thin Hydra entry point (conf/replay.yaml).
"""
from __future__ import annotations

import sys
from pathlib import Path

import hydra
from omegaconf import DictConfig

CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")
VIEWERS = ("none", "web", "native")


class ConfigError(ValueError):
    """A configuration value that cannot work; the message names the key."""


def _require(ok: bool, key: str, problem: str) -> None:
    if not ok:
        raise ConfigError(f"config key '{key}': {problem}")


def _int(cfg: DictConfig, key: str, minimum: int = 0) -> int:
    v = cfg.get(key)
    _require(isinstance(v, int) and not isinstance(v, bool) and v >= minimum, key,
             f"must be an integer >= {minimum}, got {v!r}")
    return int(v)


def run(cfg: DictConfig) -> Path:
    from hydra.utils import to_absolute_path

    from pipeline.records.replay import ReplayError, build_replay, open_viewer

    _require(cfg.get("file") not in (None, "", "???"), "file", "give the record file: file=<path.mcap>")
    path = Path(to_absolute_path(str(cfg.file)))
    _require(path.is_file(), "file", f"no such record file: {path}")
    run_id, whole = _int(cfg, "run"), cfg.get("whole_run")
    _require(isinstance(whole, bool), "whole_run", f"must be true or false, got {whole!r}")
    episode = _int(cfg, "episode")
    _require(cfg.viewer in VIEWERS, "viewer", f"must be one of {VIEWERS}, got {cfg.viewer!r}")
    for key in ("web_port", "grpc_port"):
        _require(0 <= _int(cfg, key) < 65536, key, "must be a port number")
    stem = path.name.removesuffix(".partial").removesuffix(".mcap")
    out = cfg.out or f"replays/{stem}-run{run_id}-" + ("all" if whole else f"ep{episode}") + ".rrd"
    out = Path(to_absolute_path(str(out)))
    _require(out.suffix == ".rrd", "out", f"must end in .rrd, got {out}")
    try:
        rrd = build_replay(path, run_id, None if whole else episode, out=out, whole_run=whole)
    except ReplayError as exc:
        raise ConfigError(f"config keys 'run'/'episode': {exc}") from None
    print(f"wrote {rrd}  (open it with: rerun {rrd})", flush=True)
    open_viewer(rrd, cfg.viewer, bind=str(cfg.bind), web_port=int(cfg.web_port), grpc_port=int(cfg.grpc_port))
    return rrd


@hydra.main(config_path=CONF_DIR, config_name="replay", version_base="1.3")
def _main(cfg: DictConfig) -> None:
    try:
        run(cfg)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


def main() -> None:
    """Accept the record file as a positional argument too (``replay <file.mcap> run=3``)."""
    args = sys.argv[1:]
    for i, a in enumerate(args):
        if "=" not in a and not a.startswith("-") and (a.endswith(".mcap") or a.endswith(".mcap.partial")):
            args[i] = "file=" + "'" + a.replace("'", "\\'") + "'"
    sys.argv[1:] = args
    _main()


if __name__ == "__main__":
    main()
