"""The memory a trial takes in the runner (:func:`pipeline.rl.runner.run_trials`) and the memory
the machine has, so that a trial too large for the machine is refused before it starts."""

from __future__ import annotations

import os
from pathlib import Path

from pipeline.rl.trace_pool import TRACE_CAPACITY


def memory_estimate(runs: int, episodes: int, n_cells: int, record_steps: bool) -> int:
    """Bytes the runner's arrays take for one cell of ``runs`` x ``episodes`` on a maze of
    ``n_cells`` cells: per-episode results (22 bytes a run-episode), Q and A_d (36 bytes a
    run-cell-action), the step trace when recording steps (10 bytes x ``TRACE_CAPACITY`` steps a
    run) and the per-run summaries."""
    per_run = episodes * 22 + n_cells * 4 * 9 + (TRACE_CAPACITY * 10 if record_steps else 0) + 2048
    return runs * per_run


def available_memory() -> int:
    """``MemAvailable`` of /proc/meminfo (bytes); the physical memory where that is missing."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
