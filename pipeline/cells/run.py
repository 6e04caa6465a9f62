"""One cell of a trials run: what it runs with (its config, layout, recogniser and the pictures its
records keep) and running it into its folder (``records.mcap``, ``summary.json``).

The stage (:mod:`pipeline.stages.trials`) and its worker processes (:mod:`pipeline.cells.workers`)
both run cells through :func:`run_cell`. Here the runner (``pipeline/rl``) meets the record writer
(``pipeline/records``): the runner writes through the ``EpisodeSink`` protocol and knows no file
format, the writer knows no runner, so the stage joins them.
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from pipeline.config.compose import one_line
from pipeline.config.fields import refuse
from pipeline.config.recognisers import build_recogniser
from pipeline.errors import Interrupted, UserError
from pipeline.files import disk_problem, size_text, write_json_atomic
from pipeline.rl.methods import MethodSpec
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import Rule
from pipeline.rl.run_world import run_placement
from pipeline.rl.runner import run_trials
from pipeline.schemas.trials import TrialsConfig
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import ACTION_NAMES, MOVES, Layout
from pipeline.world.pictures import CATEGORIES

if TYPE_CHECKING:  # the records package is imported where a cell records
    from pipeline.records.config_text import ConfigText, Pieces


@dataclass
class CellRun:
    """One cell as it runs: its full single-cell config (what the records embed) and its layout."""

    name: str
    config: TrialsConfig
    layout: Layout
    recogniser: Any = None
    """Built before any cell runs, so a broken checkpoint is refused up front (in the process
    that runs the cell: the stage's, or a worker's)."""
    pictures: dict[int, bytes] = field(default_factory=dict)
    """The query pictures the records keep, by picture id (read up front, like the recogniser)."""
    support: dict[int, list[bytes]] = field(default_factory=dict)
    """The initial support set the records keep: category -> its K shots in position order."""
    recogniser_key: str = "recogniser"
    """The config key an error in building the recogniser names (a cell's own where it pins one)."""

    @property
    def method(self) -> MethodSpec:
        return self.config.method


class CellTime(NamedTuple):
    """Wall seconds of a cell's trial (its records written meanwhile) and, of them, inside the
    compiled kernel: what the stage's timing file holds (``timing_file``)."""

    seconds: float
    kernel_seconds: float


def recogniser_key(cfg: TrialsConfig) -> str | None:
    """What makes two cells' recognisers interchangeable: the recogniser's arguments and the
    substitution way. None where a recogniser must not be shared: no recogniser, or a support set
    carried over from run to run (it is state of the cell's own runs)."""
    method = cfg.method
    if not method.uses_recogniser or cfg.support == "carry":
        return None
    way = cfg.substitution if method.dynamic_support else 0
    return json.dumps([cfg.recogniser, way], sort_keys=True, default=str)


def make_recogniser(cfg: TrialsConfig, key: str = "recogniser", built: dict | None = None):
    """The cell's recogniser (``conf/recogniser/``), or None for methods that see no pictures;
    ``key`` names the config key in an error (a cell's own when it pins recogniser arguments).

    ``built`` (:func:`recogniser_key` -> recogniser) shares one recogniser among cells: each run
    restores its own support set from the original at its start (``start_run``), so a recogniser
    that served other cells' runs gives the same answers (loading the Relation Network once instead
    of once per cell: 600 times in the generalisation experiment)."""
    method = cfg.method
    if not method.uses_recogniser:
        return None
    share = recogniser_key(cfg) if built is not None else None
    if share is not None and share in built:
        recogniser = built[share]
    else:
        way = cfg.substitution if method.dynamic_support else 0
        if cfg.progress:  # loading torch and a checkpoint takes seconds: say so first
            way_text = f", substitution way {way}" if way else ""
            print(
                f"loading the recogniser {_described(cfg.recogniser)}{way_text} ...",
                file=sys.stderr,
            )
        recogniser = build_recogniser(
            cfg.recogniser, substitution_way=way, carry_over=cfg.support == "carry", key=key
        )
        if share is not None:
            built[share] = recogniser
    # the robot's cells share the grid's recogniser (each run restores its support set) and see
    # their live pictures through a wrapper made with the cell's world (:func:`cell_world`)
    return recogniser


def _described(recogniser: dict) -> str:
    """``RelationRecogniser (datasets/models/relation_net.pt)``: its class and checkpoint."""
    parts = str(recogniser.get("_target_", "?")).split(".")
    name = next((p for p in reversed(parts) if p[:1].isupper()), parts[-1])
    return name + (f" ({recogniser['checkpoint']})" if recogniser.get("checkpoint") else "")


def cell_world(cell: CellRun):
    """The world the cell runs in (``pipeline.rl.run_world``): the grid, or the camera robot with
    every run's live pictures rendered (a bar on stderr with ``progress``) and the cell's
    recogniser wrapped to answer them (``pipeline.robot.live``; one that cannot is refused)."""
    from pipeline.rl.run_world import GRID

    cfg = cell.config
    if cfg.world != "robot3d":
        return GRID, cell.recogniser
    from tqdm.auto import tqdm

    from pipeline.robot.live import live
    from pipeline.robot.live_world import RobotSettings, RobotWorld

    if cfg.support == "carry":
        refuse("support", "world=robot3d runs support=restore only")
    try:
        settings = RobotSettings(cfg.robot.cell, cfg.robot.timestep)
    except ValueError as exc:
        refuse("robot", str(exc))
    try:
        world = RobotWorld(cell.layout, settings, live_pictures=cell.method.uses_recogniser)
    except ValueError as exc:
        refuse("maze", f"world=robot3d: {exc}")
    world.describe()  # the motion table: a cell size it cannot run is refused before any run
    if not world.live_pictures:
        return world, cell.recogniser
    geometry = build_geometry(cell.layout)
    desc = f"{_named(cell)}: live pictures"
    bar = tqdm(range(cfg.runs), desc=desc, unit="run", disable=not cfg.progress, leave=False)
    try:
        for r in bar:
            world.run_world(geometry, cfg.seed, r)
    except ValueError as exc:
        refuse("runs", f"world=robot3d: {exc}")
    finally:
        bar.close()
    try:
        return world, live(cell.recogniser, world)
    except ValueError as exc:
        refuse(cell.recogniser_key, f"world=robot3d: {exc}")


def pictures_dir(cfg: TrialsConfig) -> str | None:
    """The rendered pictures the records keep, for methods that recognise pictures: the recogniser's
    own ``images_dir`` (relation_net), else the trials key ``images_dir`` (oracle, fixed_accuracy)."""
    own = cfg.recogniser.get("images_dir")
    if not cfg.method.uses_recogniser or not (own or cfg.images_dir):
        return None
    if own and cfg.images_dir and Path(own).resolve() != Path(cfg.images_dir).resolve():
        refuse(
            "images_dir",
            f"the recogniser reads its pictures from recogniser.images_dir="
            f"{own}, and the records keep those; leave images_dir out",
        )
    return own or cfg.images_dir


def recorded_pictures(cfg: TrialsConfig) -> tuple[dict[int, bytes], dict[int, list[bytes]]]:
    """The query pictures and the initial support set the records keep (none without ``record`` or
    a :func:`pictures_dir`); a folder that is not a rendered dataset is refused, naming the key."""
    images_dir = pictures_dir(cfg) if cfg.record != "none" else None
    if images_dir is None:
        return {}, {}
    from pipeline.fewshot.picture_bytes import query_pictures, support_pictures

    try:
        return query_pictures(images_dir), support_pictures(images_dir)
    except (UserError, OSError) as exc:  # no manifest, missing or unreadable pictures
        key = "images_dir" if cfg.images_dir else "recogniser.images_dir"
        refuse(key, one_line(exc))


#: The pieces of the recorded config (:mod:`pipeline.records.config_text`) of every key but the
#: maze, by everything but the maze: the cells of a study over generated layouts differ only there,
#: and rendering a config's text (about 3 ms) 2,100 times would cost more than their trials.
_RECORDED: dict[str, Pieces] = {}

#: Keys that say how cells were run, not what: left out of the records, so the records of a cell
#: are the same bytes whether it ran alone or beside others.
NOT_RECORDED = ("workers",)


def recorded_config(cell: CellRun) -> ConfigText:
    """The config embedded in the records: the cell's own, as it ran (without :data:`NOT_RECORDED`)."""
    from pipeline.records.config_text import joined, pieces

    rest = replace(cell.config, maze="")
    key = repr(rest)
    if key not in _RECORDED:
        # the config as it ran is a resolved dataclass: read directly, not through OmegaConf (the
        # same text for every cell of every experiment, tested; 3 ms, not 54 ms, a new cell)
        whole = asdict(rest)
        shared = {k: v for k, v in whole.items() if k not in NOT_RECORDED and k != "maze"}
        _RECORDED[key] = pieces(shared)
    return joined(_RECORDED[key] | pieces({"maze": cell.config.maze}))


def open_records(cell: CellRun, folder: Path, world=None, recogniser=None):
    """The record writer of ``folder / records.mcap`` (docs/records.md): the config, seeds and cell
    as metadata, the maze, each run's obstacle placement and the pictures the records keep (the
    robot's: its live pictures, and its motion table as ``info.robot``)."""
    from pipeline.records.writer import RecordWriter

    cfg, layout, runs, seed = cell.config, cell.layout, cell.config.runs, cell.config.seed
    geometry = build_geometry(layout)
    recogniser = cell.recogniser if recogniser is None else recogniser
    describe = getattr(recogniser, "describe", None)
    robot = world is not None and world.name == "robot3d"
    pictures = (world.picture_png() if world.live_pictures else {}) if robot else cell.pictures
    return RecordWriter(
        folder / "records.mcap",
        metadata={
            "config": recorded_config(cell),
            "seeds": {"seed": seed, "runs": {r: asdict(run_seeds(seed, r)) for r in range(runs)}},
            "info": {
                "cell": cell.name,
                "method": cell.method.as_dict(),
                "maze": layout.name,
                "substitution": cfg.substitution,
                "support": cfg.support,
                "recogniser": describe() if describe is not None else None,
            },
            **({"robot": world.describe()} if robot else {}),
        },
        maze={
            "layout": list(layout.rows),
            "name": layout.name,
            "categories": list(CATEGORIES),
            "actions": ACTION_NAMES,
            "moves": MOVES,
        },
        runs=[run_placement(geometry, seed, r).as_records(layout.obstacles) for r in range(runs)],
        pictures=pictures,
        support_pictures=cell.support,
        flush_every=cfg.flush_every,
        steps=cfg.record == "steps",
        fsync=False,  # the folder is a staging folder, synced once before it is swapped in
    )


def _close_quietly(writer) -> None:
    """Finish a failed cell's records as partial; a disk that refuses even that is not a second error
    (the stage removes a failed run's staging folder)."""
    if writer is not None:
        with contextlib.suppress(OSError):
            writer.close(complete=False)


def _named(cell: CellRun) -> str:
    return f"cell {cell.name!r}" if cell.name else "the run"


def _space_needed(cell: CellRun, folder: Path, writer) -> str:
    """What the cell needs on disk, from what it wrote for the episodes it finished."""
    written = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    done, total = (writer.n_episodes if writer else 0), cell.config.runs * cell.config.episodes
    where = _named(cell)
    if done == 0:
        return f"{where} wrote {size_text(written)} before its first episode"
    return (
        f"{where} needs about {size_text(written * total / done)}: it wrote "
        f"{size_text(written)} for {done:,} of {total:,} episodes"
    )


def run_cell(cell: CellRun, folder: Path, progress: bool | None = None) -> tuple[dict, CellTime]:
    """Run one cell into ``folder`` (records, ``summary.json``); its summary and its time.
    ``progress``: the runner's per-episode bar (default ``cfg.progress``)."""
    cfg, method = cell.config, cell.method
    try:
        world, recogniser = cell_world(cell)
    except KeyboardInterrupt:
        raise Interrupted(130, f"interrupted before {_named(cell)} ran; nothing recorded") from None
    try:
        writer = open_records(cell, folder, world, recogniser) if cfg.record != "none" else None
    except OSError as exc:
        raise (
            disk_problem(exc, folder, f"{_named(cell)} could not start its records") or exc
        ) from None
    t0 = time.perf_counter()
    try:
        result = run_trials(
            cell.layout,
            method,
            cfg.runs,
            cfg.episodes,
            cfg.seed,
            recogniser=recogniser,
            sink=writer,
            progress=cfg.progress if progress is None else progress,
            shared_support=cfg.support == "carry",
            world=world,
            rule=Rule[cfg.rule],
            threshold=cfg.threshold,
        )
    except (KeyboardInterrupt, Interrupted) as exc:
        code = exc.code if isinstance(exc, Interrupted) else 130
        if writer is None:
            raise Interrupted(
                code, f"interrupted; nothing recorded (record=none); {folder} left as it was"
            ) from None
        path = writer.close(complete=False)
        raise Interrupted(
            code, f"interrupted; partial records at {path}: {writer.n_episodes} episodes"
        ) from None
    except OSError as exc:
        _close_quietly(writer)
        raise disk_problem(exc, folder, _space_needed(cell, folder, writer)) or exc from None
    except BaseException:
        _close_quietly(writer)
        raise
    seconds = time.perf_counter() - t0
    summary = result.summary()
    summary.update(
        {
            "cell": cell.name,
            "method_spec": method.as_dict(),
            "substitution": cfg.substitution,
            "support": cfg.support,
        }
    )
    try:
        if writer is not None:
            writer.close()
        # no wall-clock figures: same seed, same bytes
        write_json_atomic(folder / "summary.json", summary, fsync=False)  # synced with staging
    except OSError as exc:
        raise disk_problem(exc, folder, _space_needed(cell, folder, writer)) or exc from None
    return summary, CellTime(seconds, result.kernel_seconds)
