"""Running an experiment's cells one after another, or side by side in worker processes (the
trials key ``workers``).

The cells of an experiment are independent: each has its own seed-derived runs and writes only
its own folder, so running them in any order, in any process, gives the same bytes. The parent
sends each worker the cell's config and layout (not its recogniser: a worker builds each
recogniser it needs once, :func:`pipeline.cells.run.make_recogniser`, and reads the recorded
pictures once); it collects each cell's summary, and the stage writes the experiment's index and
metrics in cell order, as with one process.

Workers are started with ``spawn`` (torch's and numba's thread pools are not safe across
``fork``); numba's compiled kernels come from its on-disk cache. Each worker applies the trials
thread budget (:func:`pipeline.threads.trials_budget`): ``threads`` numba threads
(``threads=0``: the cores divided among the workers) and one torch thread.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path

from pipeline.cells.run import (
    CellRun,
    CellTime,
    make_recogniser,
    pictures_dir,
    recorded_pictures,
    run_cell,
)
from pipeline.errors import Interrupted
from pipeline.threads import ThreadBudget, trials_budget

#: Per worker process: recognisers by :func:`~pipeline.cells.run.recogniser_key`, pictures by folder.
_BUILT: dict = {}
_PICTURES: dict = {}
_BUDGET: list[ThreadBudget] = [trials_budget(0, 1)]


#: How often a worker looks whether the stage that started it is still there (seconds).
PARENT_CHECK_SECONDS = 0.5


def _start_worker(budget: ThreadBudget, parent: int) -> None:
    _BUDGET[0] = budget.apply()
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    # tqdm would make a multiprocessing lock (a named semaphore) even for the disabled bars of a
    # worker; a stopped worker never frees it and the resource tracker complains at exit
    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())


def _exit_with_parent(parent: int) -> None:
    """End this worker once the stage process ``parent`` is gone (``kill -9`` of the stage gives
    its workers no signal: they would otherwise run on, orphans holding memory and cores)."""
    while os.getppid() == parent:
        time.sleep(PARENT_CHECK_SECONDS)
    os._exit(1)


def _recogniser(cell: CellRun):
    """In a worker: ``cell``'s recogniser, built once per process where cells may share it."""
    recogniser = make_recogniser(cell.config, cell.recogniser_key, built=_BUILT)
    _BUDGET[0].apply()  # torch's share, now that a recogniser may have imported it
    return recogniser


def _check_recogniser(cell: CellRun) -> None:
    """In a worker, before any cell runs: build ``cell``'s recogniser (kept for the cells this
    worker runs), so that a broken checkpoint or argument stops the stage up front."""
    _recogniser(cell)


def _run_one(cell, folder: str) -> tuple[dict, float]:
    """In a worker: give ``cell`` its recogniser and pictures (built once per process), run it."""
    recogniser = _recogniser(cell)
    shown = pictures_dir(cell.config) if cell.config.record != "none" else None
    if shown not in _PICTURES:
        _PICTURES[shown] = recorded_pictures(cell.config)
    return run_cell(
        replace(
            cell, recogniser=recogniser, pictures=_PICTURES[shown][0], support=_PICTURES[shown][1]
        ),
        Path(folder),
        progress=False,
    )


def cell_results(
    cells: list[CellRun], out: Path, pool: ProcessPoolExecutor | None, progress: bool
) -> Iterator[tuple[int, dict, CellTime]]:
    """``(index, summary, spent)`` of every cell into ``out`` (``<out>/<cell>/``, or ``out``
    itself for the one unnamed cell) as it completes: one after another, or in the ``pool``'s
    processes (:func:`worker_pool`, without per-episode bars); ``progress``: each cell's bar."""
    folders = [out / c.name if c.name else out for c in cells]
    if pool is not None:
        try:
            yield from run_parallel(pool, cells, folders)
        except (KeyboardInterrupt, Interrupted) as exc:  # the workers are stopped: say where
            code = exc.code if isinstance(exc, Interrupted) else 130
            raise Interrupted(
                code, f"interrupted; the finished cells' records are under {out}"
            ) from None
        return
    for i, (cell, folder) in enumerate(zip(cells, folders)):
        yield i, *run_cell(cell, folder, progress)


@contextlib.contextmanager
def worker_pool(
    cells: list[CellRun], workers: int, threads: int
) -> Iterator[ProcessPoolExecutor | None]:
    """``workers`` processes for ``cells`` (None for one process or one cell), each with the trials
    thread budget. Every distinct recogniser the cells need is built by a worker before this
    returns, so a broken checkpoint or argument stops the stage before it touches any folder. The
    workers are stopped when the block ends, however it ends."""
    if workers <= 1 or len(cells) <= 1:
        yield None
        return
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_start_worker,
        initargs=(trials_budget(threads, workers), os.getpid()),
    )
    try:
        checks = {recogniser_check_key(c.config): c for c in cells if c.method.uses_recogniser}
        light = [replace(c, recogniser=None, pictures={}, support={}) for c in checks.values()]
        for future in [pool.submit(_check_recogniser, c) for c in light]:
            future.result()
        yield pool
    except BaseException:
        stop(pool)
        raise
    # a worker that ends on its own saves the score columns it computed (score_cache, at exit)
    pool.shutdown()


def run_parallel(
    pool: ProcessPoolExecutor, cells: list[CellRun], folders: list[Path]
) -> Iterator[tuple[int, dict, CellTime]]:
    """``(index, summary, spent)`` of every cell as it completes, run in the ``pool``. An error
    in a cell stops the others and is raised here; so is an interrupt."""
    light = [replace(c, recogniser=None, pictures={}, support={}) for c in cells]
    try:
        pending = {
            pool.submit(_run_one, cell, str(folder)): i
            for i, (cell, folder) in enumerate(zip(light, folders))
        }
        # one waiter for all the cells: waiting anew after each cell costs the parent work in
        # proportion to the cells left (2,100 cells: seconds of a core the workers need)
        for future in as_completed(pending):
            summary, spent = future.result()
            yield pending[future], summary, spent
    except BaseException:
        stop(pool)
        raise


def recogniser_check_key(cfg) -> str:
    """Cells whose recognisers are built from the same arguments, way and support policy."""
    way = cfg.substitution if cfg.method.dynamic_support else 0
    return json.dumps([cfg.recogniser, way, cfg.support], sort_keys=True, default=str)


def stop(pool: ProcessPoolExecutor) -> None:
    """Cancel the cells not started and end the workers this pool started."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=5)
    pool.shutdown(
        wait=True
    )  # joins the pool's manager thread, which else fails at the interpreter's exit
