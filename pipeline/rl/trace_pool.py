"""Step traces lent from one trial to the next of the same process.

A recording trial keeps each run's steps in a :class:`~pipeline.rl.structs.Trace` of ``runs x
capacity`` entries (10 bytes a step). A fresh one's pages are mapped as the kernel first writes
them, and on this machine those page faults cost more CPU than recording the steps
(``benchmarks.records_overhead``): so a finished trial gives its trace back, and the next trial of
that shape in the process (the next cell of a study) borrows it instead. A trace is lent to one
trial at a time; what it held is never read again (its lengths say what is there).
"""

from __future__ import annotations

from pipeline.rl.structs import Trace

#: Steps a run's trace holds (10 bytes a step): a run's episodes go to the sink when it is full and
#: at the end of the trial, so a paper-scale 11x11 run (about 23,500 steps) is one batch (the
#: recording costs per batch).
TRACE_CAPACITY = 32768

_SPARE: dict[tuple[int, int], Trace] = {}  # (runs, capacity) -> the last trace given back


def borrow(runs: int, capacity: int) -> Trace:
    """A recording trace of ``runs x capacity`` steps, empty: a spare one or a new one."""
    spare = _SPARE.pop((runs, capacity), None)
    if spare is None:
        return Trace.empty(runs, capacity, True)
    spare.length[:] = 0
    return spare


def give_back(trace: Trace) -> None:
    """Keep ``trace`` for the next trial of its shape (its lender no longer uses it)."""
    if trace.record:
        _SPARE[trace.states.shape] = trace
