"""The test session's two pieces of set-up for pytest-xdist (``make test`` runs ``-n auto --dist
loadfile``, a test file's tests on one worker).

Each worker process is pinned to its own share of the cores before any test module is imported.
Without it every worker, and every stage a test starts, sizes its numba and torch thread pools to
all the cores (``pipeline.threads.cores`` reads the affinity mask), and two workers' pools fight:
on 2 cores a torch training test took 24 s instead of 2. Child processes inherit the mask.

The files go to the workers longest first (the last run's durations, kept in pytest's cache), so
that no long file starts while the other workers are finishing: the tail where one worker runs
alone is at most one short file. A file without durations yet goes first; with none at all (a
fresh clone) the files with the most tests go first, as xdist's own order does.
"""

from __future__ import annotations

import os
from collections import Counter

#: Tests keep no score files between runs (pipeline/fewshot/score_cache.py): a test that needs them
#: names its own folder. Set before any test imports the pipeline; stages a test starts inherit it.
os.environ["FSRL_SCORE_CACHE"] = "off"

#: The pytest cache key of each test's last duration (set-up, call and tear-down, seconds).
DURATIONS = "safenav/durations"

#: What a test without a recorded duration is taken to last (seconds): its file goes early.
UNTIMED = 10.0

_durations: dict[str, float] = {}


def pytest_configure(config) -> None:
    worker = os.environ.get("PYTEST_XDIST_WORKER")  # gw0, gw1, ... in a worker; unset otherwise
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if worker is None or workers < 2 or not hasattr(os, "sched_setaffinity"):
        return
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) >= workers:  # more workers than cores: leave the scheduler to share them
        os.sched_setaffinity(0, cpus[int(worker.removeprefix("gw")) :: workers])


def pytest_collection_modifyitems(config, items) -> None:
    """The files longest first, each file's tests in their own order (xdist keeps this order with
    ``--no-loadscope-reorder``)."""
    known = config.cache.get(DURATIONS, {}) if getattr(config, "cache", None) else {}
    cost: Counter = Counter()
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        file = item.nodeid.split("::")[0]
        cost[file] += known.get(item.nodeid, UNTIMED) if known else 1.0
        first.setdefault(file, i)
    order = {
        file: rank for rank, file in enumerate(sorted(first, key=lambda f: (-cost[f], first[f])))
    }
    items.sort(key=lambda item: order[item.nodeid.split("::")[0]])


def pytest_runtest_logreport(report) -> None:
    """On the controlling process (under xdist, the workers' reports too): each test's duration."""
    _durations[report.nodeid] = _durations.get(report.nodeid, 0.0) + report.duration


def pytest_sessionfinish(session) -> None:
    config = session.config
    if hasattr(config, "workerinput") or not _durations or not getattr(config, "cache", None):
        return  # a worker: the controlling process keeps the durations
    config.cache.set(DURATIONS, {**config.cache.get(DURATIONS, {}), **_durations})
