"""Replay a recorded episode (or a whole run) in Rerun from the MCAP records alone (the entities:
docs/records.md "Replay it in Rerun"). Moves, action and category names come from the file's maze
metadata; a file without moves gets :data:`.story.NESW`, there and nowhere else.

The recorded config's ``world`` picks the drawing (:func:`drawing_of`): the grid's
:class:`.draw.Replay`, or the robot's :class:`.robot3d.RobotReplay` in 3D with the run as the
world's own reader reads it (``worlds``: :func:`pipeline.robot.replay.robot_run`, which the stage
``replay`` hands in). Both read the one record file through :func:`pipeline.records.read_records`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pipeline.errors import UserError
from pipeline.files import disk_problem, size_text, write_atomic
from pipeline.records import FileMeta, Records, RecordsError, read_records

from .notes import ReplayError, empty_views, first_recognition

if TYPE_CHECKING:
    from .story import Story

APPLICATION = "fewshot_safe_rl_replay"
#: The recorded config's ``world`` values (``pipeline/config/experiment.WORLDS``).
GRID_WORLD, ROBOT_WORLD = "grid", "robot3d"


#: How a world other than the grid reads a run of its records for the replay, by the recorded
#: config's ``world``: ``(meta, run) -> what its drawing needs``, raising a ``UserError`` for
#: records it cannot use (``{"robot3d": pipeline.robot.replay.robot_run}``).
Worlds = Mapping[str, Callable[[FileMeta, int], Any]]


def drawing_of(rec, recs: Records, run: int, worlds: Worlds) -> Story:
    """The drawing of run ``run`` of ``recs`` into ``rec``, by the ``world`` of the recorded config:
    the grid's :class:`.draw.Replay` (also for a file without the key), or the robot's in 3D with
    the run as ``worlds["robot3d"]`` reads it."""
    meta = recs.meta
    world = (meta.config if isinstance(meta.config, dict) else {}).get("world") or GRID_WORLD
    if world == GRID_WORLD:
        from .draw import Replay  # the drawing modules load with Rerun (.notes)

        return Replay(rec, recs, run)
    if world != ROBOT_WORLD:
        raise ReplayError(
            f"{meta.path}: config world: {world!r} is not a world the replay draws "
            f"({GRID_WORLD}, {ROBOT_WORLD})",
            key="file",
        )
    if world not in worlds:
        raise ReplayError(
            f"{meta.path}: a robot cell (config world: {world}): its replay reads the robot's "
            "records with pipeline.robot.replay.robot_run; pass worlds={'robot3d': robot_run} "
            "(python -m pipeline replay does)",
            key="file",
        )
    from .robot3d import RobotReplay

    return RobotReplay(rec, recs, run, worlds[world](meta, run))


def cell_of(path: str | Path) -> tuple[str, str]:
    """(experiment, cell) of a record file from its folders: ``<experiment>/<cell>/records.mcap``."""
    folder = Path(path).resolve().parent
    return folder.parent.name, folder.name


def replay_stem(path: str | Path, run: int, episode: int | None = None) -> str:
    """The replay's default name, ``<experiment>-<cell>-run3-ep120`` (``-all`` for a whole run),
    from the record file's folders; a file not called ``records.mcap`` adds its own stem."""
    stem = Path(path).name.removesuffix(".partial").removesuffix(".mcap")
    parts = [*cell_of(path), *([stem] if stem != "records" else [])]
    return (
        "-".join(p for p in parts if p)
        + f"-run{run}-"
        + ("all" if episode is None else f"ep{episode}")
    )


def recording_name(meta: FileMeta, run: int, episode: int | None = None) -> str:
    """What the viewer lists, ``fig8/fewshot_dss run 3 ep 120``: the experiment and cell of the file's
    config and info metadata, else of its folders (:func:`cell_of`)."""
    experiment = (meta.config or {}).get("experiment")
    experiment = experiment.get("name") if isinstance(experiment, dict) else experiment
    info = meta.info.get("info")  # the trials stage's info record: cell, method, maze, ...
    cell = info.get("cell") if isinstance(info, dict) else None
    folders = cell_of(meta.path)
    return f"{experiment or folders[0]}/{cell or folders[1]} run {run} " + (
        "all episodes" if episode is None else f"ep {episode}"
    )


def read_run(path: Path, run: int, episode: int | None) -> Records:
    """The records of ``run``, checked to hold ``episode`` (any episode when None) and a maze."""
    try:
        recs = read_records(path, run=run)
    except RecordsError as exc:  # missing, empty, not MCAP, another program's
        raise ReplayError(str(exc), key="file") from None
    meta = recs.meta
    if meta.unusable:  # our magic bytes and nothing readable after them
        raise ReplayError(meta.unusable, key="file")
    if meta.record != "steps":  # record=episodes: summaries and events, no step to draw
        raise ReplayError(
            f"{path}: recorded with record={meta.record}: it holds no steps to replay; run the cell "
            "again with record=steps (the default) to replay it",
            key="file",
        )
    lost = meta.lost or "; ".join(meta.problems)  # the problems, where its config is lost too
    why = f"; the file is damaged or cut: {lost}" if lost and not meta.complete else ""
    have = recs.episodes.episode[recs.episodes.run == run]
    if have.empty:
        raise ReplayError(f"{path}: no recorded episode of run {run}{why}")
    if episode is not None and episode not in set(have):
        raise ReplayError(
            f"{path}: run {run} has no recorded episode {episode} "
            f"(episodes {int(have.min())}..{int(have.max())}, {len(have)} recorded){why}"
        )
    if not meta.maze:
        raise ReplayError(
            f"{path}: the file holds no maze metadata, so the maze cannot be drawn", key="file"
        )
    return recs


def opening_episode(path: str | Path, run: int) -> tuple[int, str]:
    """The episode a replay of ``run`` opens on when none is given (the first with a
    recognition: :func:`.notes.first_recognition`), with a sentence saying why."""
    return first_recognition(read_run(Path(path), run, None), run)


def build_replay(
    path: str | Path,
    run: int,
    episode: int | None = None,
    *,
    out: str | Path,
    whole_run: bool = False,
    worlds: Worlds | None = None,
) -> Path:
    """Write a Rerun ``.rrd`` replaying ``episode`` of ``run`` of the record file ``path`` (every
    episode of the run with ``whole_run=True``) and return its path; ``worlds``: the readers of
    worlds other than the grid (:data:`Worlds`). The reader's warnings about a damaged or cut file
    pass through to the caller; a world's ``UserError`` is a :class:`ReplayError` of the file."""
    import rerun as rr

    path, out = Path(path), Path(out)
    if not whole_run and episode is None:
        raise ReplayError("pass an episode, or whole_run=True to replay every episode of the run")
    shown = None if whole_run else int(episode)
    recs = read_run(path, run, shown)
    have = recs.episodes.episode[recs.episodes.run == run]
    rec = rr.RecordingStream(
        APPLICATION, send_properties=False, recording_id=replay_stem(path, run, shown)
    )
    episodes = sorted(set(have)) if whole_run else [shown]
    empty, name = empty_views(recs, run, episodes), recording_name(recs.meta, run, shown)
    try:
        replay = drawing_of(rec, recs, run, worlds or {})
        stream = rec.binary_stream()  # in memory, then written atomically: a full or read-only
        rec.send_blueprint(replay.blueprint(name, empty))  # disk is an OSError, never a cut .rrd
        rec.send_recording_name(name)
        replay.draw(episodes, empty)
    except ReplayError:
        raise
    except UserError as exc:  # a world's reader refused its records: the file's
        raise ReplayError(str(exc), key="file") from None
    data = stream.read(flush=True) or b""
    rec.disconnect()
    return write_rrd(out, data)


def write_rrd(out: Path, data: bytes) -> Path:
    """Write a replay's bytes to ``out`` whole or not at all, creating its folder; a full or
    read-only disk is a :class:`pipeline.files.DiskError` saying how much the replay needs."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        return write_atomic(out, data)
    except OSError as exc:
        problem = disk_problem(exc, out.parent, f"the replay needs {size_text(len(data))}")
        if problem is None:
            raise
        raise problem from None
