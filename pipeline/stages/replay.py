"""Stage ``replay``: a Rerun recording of one recorded episode (or run) from an MCAP record file.

    python -m pipeline replay file=<file.mcap> run=3 episode=120 [whole_run=true] [viewer=web|native]

Without ``episode`` the replay opens the run's first episode with a recognition (and says so).
A robot cell (its recorded config says ``world: robot3d``; docs/robot3d.md) replays in 3D from its
``records.mcap`` as a grid cell does: this stage hands the robot's reader
(:func:`pipeline.robot.replay.robot_run`) to the replay (:data:`WORLDS`).

The file may also be given positionally (``python -m pipeline replay <file.mcap> run=3 ...``).
The recording is built by :mod:`pipeline.replay` and shown by its viewer process
(:mod:`pipeline.replay.viewer`: ``viewer=web`` or ``native``, both checked before any work); this is
the thin entry point (conf/replay.yaml).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from pipeline.config.fields import refuse
from pipeline.files import DiskError
from pipeline.schemas.replay import ReplayConfig
from pipeline.stages import stage_main


def _robot_run(meta, run: int):
    """A robot cell's run as its replay needs it (:func:`pipeline.robot.replay.robot_run`;
    imported when a robot cell is replayed: it loads MuJoCo)."""
    from pipeline.robot.replay import robot_run

    return robot_run(meta, run)


#: How the worlds beside the grid read their records for the replay (``pipeline.replay.build``
#: cannot import ``pipeline.robot``: .importlinter), by the recorded config's ``world``.
WORLDS = {"robot3d": _robot_run}


def run(cfg: ReplayConfig, overrides: list[str] = ()) -> Path:
    from pipeline.replay.viewer import check_display, open_viewer, serve_web, web_address

    path = Path(cfg.file).resolve()
    if not path.is_file():
        refuse("file", f"no such record file: {path}")
    check_display(cfg.viewer)  # refused before any work, as are the web viewer's ports
    web = None
    if cfg.viewer == "web":
        web = web_address(cfg.bind, cfg.allow_remote, cfg.web_port, cfg.grpc_port)
    rrd = write_replay(path, cfg)
    print(f"open it with: rerun {rrd}", flush=True)
    if web is not None:
        serve_web(rrd, web)
    else:
        open_viewer(rrd, cfg.viewer)
    return rrd


def write_replay(path: Path, cfg: ReplayConfig) -> Path:
    """The ``.rrd`` of ``cfg.run``/``cfg.episode``; a damaged record file warns in one line (each
    warning once, however often the file is read; none when the replay is refused)."""
    from pipeline.records import RecordsWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordsWarning)
        rrd = _write_replay(path, cfg)
    said = set()
    for w in caught:
        if not issubclass(w.category, RecordsWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        elif str(w.message) not in said:
            said.add(str(w.message))
            print(f"warning: {w.message}", file=sys.stderr, flush=True)
    return rrd


def _write_replay(path: Path, cfg: ReplayConfig) -> Path:
    from pipeline.replay import ReplayError, build_replay, opening_episode, replay_stem

    if cfg.whole_run and cfg.episode is not None:
        refuse("episode", "whole_run=true replays every episode; give one")
    episode = cfg.episode
    if episode is None and not cfg.whole_run:
        try:
            episode, why = opening_episode(path, cfg.run)
        except ReplayError as exc:
            refuse("file" if exc.key == "file" else "run", str(exc))
        print(f"episode={episode}: {why}", flush=True)
    out = cfg.out or f"replays/{replay_stem(path, cfg.run, episode)}.rrd"
    out = Path(out).resolve()
    if out.suffix != ".rrd":
        refuse("out", f"must end in .rrd, got {out}")
    try:
        rrd = build_replay(path, cfg.run, episode, out=out, whole_run=cfg.whole_run, worlds=WORLDS)
    except ReplayError as exc:
        refuse("file" if exc.key == "file" else ("run", "episode"), str(exc))
    except DiskError as exc:  # a full or read-only folder: the .rrd is written whole or not at all
        refuse("out", str(exc))
    return Path(rrd)


def main() -> None:
    """Accept the record file as a positional argument too (``replay <file.mcap> run=3``)."""
    args = sys.argv[1:]
    for i, a in enumerate(args):
        if "=" not in a and not a.startswith("-") and a.endswith((".mcap", ".mcap.partial")):
            args[i] = "file=" + "'" + a.replace("'", "\\'") + "'"
    stage_main("replay", run, args)


if __name__ == "__main__":
    main()
