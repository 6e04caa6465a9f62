"""Stage ``trials``: independent runs of the methods on the mazes, every episode recorded to MCAP.

    python -m pipeline trials method=ssrl maze=7x7 runs=100 episodes=500 seed=0 out=runs/ssrl7
    python -m pipeline trials +experiment=fig8            # every cell of one paper experiment

One cell (method, maze, substitution way, support restore/carry) writes ``summary.json`` and
``records.mcap`` into its folder: ``<out>/`` for a single cell, ``<out>/<cell>/`` for each cell
of an experiment, plus ``<out>/summary.json`` listing the cells. An ``out`` that already holds
results is refused unless ``overwrite=true`` is given (dvc.yaml's stages give it: DVC keeps their
outs, ``persist``, so a refused config leaves them in place). Everything is built in
``<out>/.staging-<pid>/`` and moved in only when complete; with ``overwrite=true`` the cells of
the previous run that this one does not have are removed then, and the staging folders of ended
runs (never a live process's: :func:`pipeline.files.abandoned`). An experiment run by hand into the
``out`` its file declares (its DVC stage's cached out) ends with a note that DVC owns that folder.

The stage composes and hands over: the cells are planned in :mod:`pipeline.cells.plan`,
each runs through :func:`pipeline.cells.run.run_cell` (one after another, or side by side
in :mod:`pipeline.cells.workers`), :mod:`pipeline.cells.progress` prints as they complete, and
:mod:`pipeline.cells.metrics` writes an experiment's DVC metrics.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any

import numba

from pipeline.cells.metrics import write_metrics
from pipeline.cells.plan import (
    experiment_cells,
    generated_key,
    parse_overrides,
    refuse_inapplicable,
)
from pipeline.cells.progress import compact, follow, prepare_kernel
from pipeline.cells.run import CellRun, make_recogniser, pictures_dir, recorded_pictures
from pipeline.cells.workers import cell_results, worker_pool
from pipeline.config.fields import refusal, refuse
from pipeline.errors import Interrupted, UserError
from pipeline.files import (
    OWNER_FILE,
    DiskError,
    abandoned,
    claim_folder,
    disk_error,
    disk_problem,
    exclusive_folder,
    remove_abandoned,
    size_text,
    swap_in,
    work_folder,
    write_index,
    write_json_atomic,
)
from pipeline.rl.memory import available_memory, memory_estimate
from pipeline.schemas.trials import TrialsConfig
from pipeline.stages import stage_main
from pipeline.threads import trials_budget
from pipeline.world.maze import load_layout

#: The fields of a cell's summary that the experiment's ``summary.json`` lists.
INDEXED = ("method", "maze", "substitution", "support", "collisions", "converged_runs")


def resolve_cells(cfg: TrialsConfig, overrides: list[str]) -> list[CellRun]:
    """The cells to run, each with its layout loaded, its recorded pictures read and its
    recogniser built (once for all the cells that ask for the same one:
    :func:`~pipeline.cells.run.make_recogniser`). Cells that will run in worker processes
    get no recogniser here: the workers build what they run, and check it before any cell starts
    (:func:`pipeline.cells.workers.worker_pool`)."""
    configs = {"": cfg} if cfg.experiment is None else experiment_cells(cfg, overrides)
    refuse_inapplicable(configs, parse_overrides(overrides))
    declared = cfg.experiment.all_cells() if cfg.experiment is not None else {}
    in_process = min(cfg.workers, len(configs)) <= 1
    built: dict[str, Any] = {}
    pictures: dict[str, tuple] = {}
    out = []
    for name, cell in configs.items():
        prefix = f"experiment.cells.{name}." if name else ""
        try:
            layout = load_layout(cell.maze)
        except UserError as exc:
            where = generated_key(cfg.experiment, name) if name else None
            refuse(where or prefix + "maze", str(exc))
        pins = name and (declared[name].recogniser or declared[name].recogniser_group)
        key = f"{prefix}recogniser" if pins else "recogniser"
        recogniser = make_recogniser(cell, key, built) if in_process else None
        shown = json.dumps([pictures_dir(cell) if cell.record != "none" else None], default=str)
        if shown not in pictures:
            pictures[shown] = recorded_pictures(cell)
        out.append(CellRun(name, cell, layout, recogniser, *pictures[shown], recogniser_key=key))
    return out


def refuse_what_does_not_fit(cfg: TrialsConfig, cells: list[CellRun]) -> None:
    """More numba threads than the machine has, or cells whose runner arrays would take more than
    80% of the available memory (:mod:`pipeline.rl.memory`), are refused before any trial runs."""
    if cfg.threads > numba.config.NUMBA_NUM_THREADS:
        refuse(
            "threads",
            f"at most {numba.config.NUMBA_NUM_THREADS} on this machine; got {cfg.threads}",
        )
    need = max(
        memory_estimate(
            c.config.runs, c.config.episodes, c.layout.n_cells, c.config.record == "steps"
        )
        for c in cells
    )
    have = available_memory()
    if need > 0.8 * have:
        refuse(
            ("runs", "episodes"),
            f"{cfg.runs} runs x {cfg.episodes} episodes need about "
            f"{need / 2**30:,.1f} GiB; this machine has {have / 2**30:,.1f} GiB available",
        )


def refuse_overwrite(cfg: TrialsConfig, out: Path) -> None:
    """Results already in ``out`` (anything but hidden entries: the lock, staging folders) are
    replaced only with ``overwrite=true``, which the stages of dvc.yaml give (their outs persist)."""
    held = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if not held or cfg.overwrite:
        return
    shown = ", ".join(held[:3]) + (", ..." if len(held) > 3 else "")
    refuse(
        "out",
        f"{out} already holds results ({shown}); give overwrite=true to "
        "replace them, or choose another out",
    )


def previous_cells(out: Path) -> set[str]:
    """The cell folders the experiment run before this one wrote into ``out`` (its
    ``summary.json`` index): ``overwrite=true`` replaces them, so those this run does not write
    are removed after the swap (``dvc repro`` keeps the out of the trials stages, ``persist``)."""
    try:
        cells = json.loads((out / "summary.json").read_text()).get("cells")
    except (OSError, ValueError, AttributeError):
        return set()
    if not isinstance(cells, dict):
        return set()
    return {n for n in cells if isinstance(n, str) and n and "/" not in n and not n.startswith(".")}


def failed_run(exc: BaseException, out: Path, staging: Path, cells: int = 1) -> BaseException:
    """What a failed run raises, after removing its staging folder (an interrupted run keeps it:
    its partial records). A full or read-only disk is one line naming ``out``, the space free
    once the staging folder is gone and what the run needs, and the staging folders of ended
    runs (never a live process's: :func:`pipeline.files.abandoned`)."""
    if isinstance(exc, (Interrupted, KeyboardInterrupt)):
        if staging.is_dir() and [p.name for p in staging.iterdir()] == [OWNER_FILE]:
            shutil.rmtree(staging, ignore_errors=True)  # nothing of the run in it
        return exc
    shutil.rmtree(staging, ignore_errors=True)
    if isinstance(exc, OSError):
        where = Path(exc.filename).parent if exc.filename else out
        exc = disk_problem(exc, where if not where.is_relative_to(staging) else out) or exc
    if not isinstance(exc, DiskError):
        return exc
    if str(staging) in str(exc):  # a cell's records: name out, and its space now staging is gone
        needed = f"{exc.needed} (one of {cells} cells)" if cells > 1 and exc.needed else exc.needed
        exc = disk_error(out, needed, exc.full, "not writable")
    stale = [
        (p, sum(f.stat().st_size for f in p.rglob("*") if f.is_file()))
        for p in abandoned(out, ".staging")
    ]
    held = "".join(
        f"; {p} (an interrupted run's partial records) holds {size_text(n)}" for p, n in stale
    )
    return refusal("out", f"{exc}{held}")


def run(cfg: TrialsConfig, overrides: list[str]) -> dict:
    for key in ("metrics_dir", "index_file"):
        if cfg.experiment is None and getattr(cfg, key):
            refuse(key, "only an experiment (+experiment=...) writes one")
    cells = resolve_cells(cfg, overrides)
    refuse_what_does_not_fit(cfg, cells)
    workers = min(cfg.workers, len(cells))
    trials_budget(cfg.threads, workers).apply()
    prepare_kernel(cfg.progress)
    with worker_pool(cells, workers, cfg.threads) as pool, exclusive_folder(cfg.out) as out:
        refuse_overwrite(cfg, out)
        staging = work_folder(out, ".staging")
        previous = previous_cells(out) if cfg.overwrite else set()
        try:
            claim_folder(staging)
            index = run_cells(cfg, cells, staging, pool)
            swap_in(staging, out)
        except BaseException as exc:
            raise failed_run(exc, out, staging, len(cells)) from None
        for name in sorted(previous - set(index.get("cells", {}))):
            shutil.rmtree(out / name, ignore_errors=True)  # a cell the experiment no longer has
        if cfg.index_file:
            write_index(out, cfg.index_file)
        for stale in remove_abandoned(out, ".staging"):  # ended runs' partial records, superseded
            print(f"removed the partial records of an interrupted run: {stale}")
    note_dvc_out(cfg, overrides)
    return index


def note_dvc_out(cfg: TrialsConfig, overrides: list[str]) -> None:
    """An experiment run by hand into the ``out`` its file declares, which is its DVC stage's
    cached out (tests/test_cli.py holds the two equal): DVC, not this run, owns that folder."""
    given = {o.lstrip("+~").split("=")[0] for o in overrides}
    if cfg.experiment is None or "out" in given or os.environ.get("DVC_STAGE"):
        return
    stage = f"trials@{cfg.experiment.name}"
    print(
        f"note: {cfg.out} is the out of DVC's stage {stage}: `dvc checkout` and `dvc exp run` "
        f"put back the copy dvc.lock names (or delete this one when DVC has none); "
        f"`dvc commit {stage}` makes this one DVC's",
        file=sys.stderr,
    )


def written(cfg: TrialsConfig, index: dict) -> list[Path | str]:
    """``out`` (an experiment) or its files (one cell), and the experiment's metrics folder and timing file."""
    out = Path(cfg.out)
    if cfg.experiment is None:
        return [
            out / "summary.json",
            *([out / "records.mcap"] if cfg.record != "none" else []),
            *filter(None, [cfg.timing_file]),
        ]
    return [out, *filter(None, [cfg.metrics_dir, cfg.index_file, cfg.timing_file])]


def run_cells(cfg: TrialsConfig, cells: list[CellRun], out: Path, pool=None) -> dict:
    """Every cell into ``out`` (the staging folder), in this process or the worker ``pool``; the
    experiment's index and metrics last, in cell order whatever the order the cells finished in."""
    progress = cfg.progress and not compact(cells)
    by_index = follow(cfg, cells, cell_results(cells, out, pool, progress))
    summaries = {c.name: by_index[i][0] for i, c in enumerate(cells)}
    if cfg.timing_file:
        timing = {c.name: _rounded(by_index[i][1]._asdict()) for i, c in enumerate(cells)}
        write_json_atomic(cfg.timing_file, timing)
    if "" in summaries:
        return summaries[""]
    cells_index = {n: {k: s[k] for k in INDEXED} for n, s in summaries.items()}
    index = {"experiment": cfg.experiment.name, "cells": cells_index}
    write_json_atomic(out / "summary.json", index)
    if cfg.metrics_dir:
        write_metrics(cfg.metrics_dir, cfg.experiment, summaries)
    return index


def _rounded(seconds: dict[str, float]) -> dict[str, float]:
    return {k: round(v, 3) for k, v in seconds.items()}


def main() -> None:
    stage_main("trials", run)
