"""What a trials run prints: first, the trial kernel being made ready (compiled on a machine's first
run, then loaded from numba's cache); as its cells complete, up to :data:`COMPACT_AT` cells, one
line each; more, a progress bar on a terminal (a line per tenth of the cells elsewhere) and a
closing line with the totals. Nothing printed here goes into the records or the summaries."""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable

from tqdm import tqdm

from pipeline.cells.run import CellRun, CellTime
from pipeline.schemas.trials import TrialsConfig

#: Above this many cells an experiment's progress is a bar (or a line per tenth), not a line per cell.
COMPACT_AT = 30


def prepare_kernel(progress: bool) -> None:
    """Compile the trial kernel, or load it from numba's cache, with a trial of one episode before
    the first cell, saying which on stderr (with ``progress``): otherwise a machine's first trial
    sits at 0% for the compilation (about 10 s on 2 cores), and worker processes would each
    compile it at once instead of loading what this process cached."""
    from pipeline.rl import kernel
    from pipeline.rl.methods import get_method
    from pipeline.rl.runner import run_trials
    from pipeline.world.maze import load_layout

    say = print if progress else lambda *args, **kwargs: None
    say(
        "preparing the trial kernel (compiled on a machine's first run, about 10 s on 2 cores; "
        "cached after) ...",
        end="",
        file=sys.stderr,
        flush=True,
    )

    def compilations() -> int:  # none where numba is off (NUMBA_DISABLE_JIT=1)
        stats = getattr(kernel.advance_batch, "stats", None)
        return sum(stats.cache_misses.values()) if stats is not None else 0

    started, before = time.perf_counter(), compilations()
    run_trials(load_layout("5x5"), get_method("qlearning"), 1, 1, progress=False)
    how = "compiled" if compilations() > before else "loaded from the cache"
    say(f" {how} in {time.perf_counter() - started:.1f} s", file=sys.stderr, flush=True)


def compact(cells: list[CellRun]) -> bool:
    """Whether the cells are too many for a line (and a per-episode bar) each."""
    return len(cells) > COMPACT_AT


def cell_line(cfg: TrialsConfig, cell: CellRun, summary: dict, seconds: float) -> str:
    c = summary["collisions"]
    label = f"{cell.name}: " if cell.name else ""
    return (
        f"{label}{cell.method.name} on {cell.layout.name}: collisions {c['mean']:.2f} +- "
        f"{c['std']:.2f} over {cfg.runs} runs, converged runs {summary['converged_runs']} "
        f"({seconds:.1f} s)"
    )


def progress_line(done: int, total: int, elapsed: float) -> str:
    """``210/2100 cells (7 s, about 63 s left)``: where a stage without a bar (``progress=false``,
    as under ``dvc repro``) stands, the time left estimated from the pace so far."""
    left = elapsed / done * (total - done) if done else float("nan")
    ahead = f", about {left:.0f} s left" if done < total else ""
    return f"{done}/{total} cells ({elapsed:.0f} s{ahead})"


def follow(
    cfg: TrialsConfig, cells: list[CellRun], results: Iterable[tuple[int, dict, CellTime]]
) -> dict[int, tuple[dict, CellTime]]:
    """``index -> (summary, spent)`` (:class:`CellTime`) of every cell, taken from ``results`` as the cells complete
    (in any order), printing the progress as it goes."""
    by_index: dict[int, tuple[dict, CellTime]] = {}
    many = compact(cells)
    t0 = time.perf_counter()
    bar = tqdm(
        total=len(cells),
        unit="cell",
        desc=cfg.experiment.name if cfg.experiment else "trials",
        disable=None if (many and cfg.progress) else True,
    )
    tenth = max(1, len(cells) // 10)
    with bar:
        for i, summary, spent in results:
            by_index[i] = (summary, spent)
            if not many:
                print(cell_line(cfg, cells[i], summary, spent.seconds))
            elif bar.disable and (len(by_index) % tenth == 0 or len(by_index) == len(cells)):
                print(
                    progress_line(len(by_index), len(cells), time.perf_counter() - t0), flush=True
                )
            bar.update()
    if many:
        steps = sum(r["steps"] for s, _ in by_index.values() for r in s["runs"])
        wall = time.perf_counter() - t0
        workers = min(cfg.workers, len(cells))
        kernel = sum(spent.kernel_seconds for _, spent in by_index.values()) / workers
        print(
            f"{len(cells)} cells x {cfg.runs} runs x {cfg.episodes} episodes: {steps:,} agent "
            f"steps in {wall:.1f} s ({steps / max(wall, 1e-9):,.0f} steps/s, {workers} "
            f"worker{'s' if workers > 1 else ''}; {kernel:.1f} s of it in the kernel a worker)"
        )
    return by_index
