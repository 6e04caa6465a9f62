"""The test session's one piece of set-up: under pytest-xdist (``make test`` runs ``-n auto``),
each worker process is pinned to its own share of the cores before any test module is imported.

Without it every worker, and every stage a test starts, sizes its numba and torch thread pools to
all the cores (``pipeline.threads.cores`` reads the affinity mask), and two workers' pools fight:
on 2 cores a torch training test took 24 s instead of 2. Child processes inherit the mask.
"""

from __future__ import annotations

import os


def pytest_configure(config) -> None:
    worker = os.environ.get("PYTEST_XDIST_WORKER")  # gw0, gw1, ... in a worker; unset otherwise
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if worker is None or workers < 2 or not hasattr(os, "sched_setaffinity"):
        return
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) >= workers:  # more workers than cores: leave the scheduler to share them
        os.sched_setaffinity(0, cpus[int(worker.removeprefix("gw")) :: workers])
