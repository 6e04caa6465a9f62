"""What a trials run prints as its cells complete: up to :data:`COMPACT_AT` cells, one line each;
more, a progress bar on a terminal (a line per tenth of the cells elsewhere) and a closing line
with the totals. Nothing printed here goes into the records or the summaries."""

from __future__ import annotations

import time
from collections.abc import Iterable

from tqdm import tqdm

from pipeline.stages._cell_run import CellRun
from pipeline.stages._trials_schema import TrialsConfig

#: Above this many cells an experiment's progress is a bar (or a line per tenth), not a line per cell.
COMPACT_AT = 30


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


def follow(
    cfg: TrialsConfig, cells: list[CellRun], results: Iterable[tuple[int, dict, float]]
) -> dict[int, tuple[dict, float]]:
    """``index -> (summary, seconds)`` of every cell, taken from ``results`` as the cells complete
    (in any order), printing the progress as it goes."""
    by_index: dict[int, tuple[dict, float]] = {}
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
        for i, summary, seconds in results:
            by_index[i] = (summary, seconds)
            if not many:
                print(cell_line(cfg, cells[i], summary, seconds))
            elif bar.disable and (len(by_index) % tenth == 0 or len(by_index) == len(cells)):
                print(
                    f"{len(by_index)}/{len(cells)} cells ({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
            bar.update()
    if many:
        steps = sum(r["steps"] for s, _ in by_index.values() for r in s["runs"])
        wall = time.perf_counter() - t0
        print(
            f"{len(cells)} cells x {cfg.runs} runs x {cfg.episodes} episodes: {steps:,} agent "
            f"steps in {wall:.1f} s ({steps / max(wall, 1e-9):,.0f} steps/s, {cfg.workers} "
            f"worker{'s' if cfg.workers > 1 else ''})"
        )
    return by_index
