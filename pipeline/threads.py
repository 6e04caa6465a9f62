"""One thread budget per process: how its cores are split between worker processes, numba (the
batched kernel) and torch (the recognisers' scores), decided once and applied on every path.

numba and torch each keep a thread pool; on a machine with other work, two pools of all the
cores fight, and a torch batch of 40 query pairs can take many times as long as on one thread. So
a trials process gives numba its share of the cores and torch one thread: the recognisers score
small batches (on a quiet machine a second torch thread gains a little: ``benchmarks.threads``),
and one torch thread everywhere keeps the recorded ``torch_threads``, and the scores, the same
whichever way the cells are spread over processes. Stages that run torch alone (meta-training,
the accuracy study) give torch their ``threads`` and leave numba alone.

The budget is applied where a process starts its work: the trials stage (one process, the parent
of workers), each worker process, the accuracy study and a Gymnasium environment that builds its
own recogniser. torch is only told its share once it is imported, so a process that runs no
recogniser never pays for importing it: a recogniser whose scores all come from the score files
imports torch at its first missing column, which then gives torch the share the process's budget
set (:mod:`pipeline.torch_later`).
"""

from __future__ import annotations

import os
import sys
from dataclasses import asdict, dataclass

#: torch's threads wherever numba runs beside it (see the module docstring).
TORCH_THREADS_BESIDE_NUMBA = 1

#: The budget this process applied last (:meth:`ThreadBudget.apply`): what torch gets when it is
#: imported later (:func:`pipeline.torch_later.import_torch`).
_APPLIED: list[ThreadBudget] = []


@dataclass(frozen=True)
class ThreadBudget:
    """``workers`` processes, each with ``numba`` kernel threads and ``torch`` intra-op threads
    (None: that library is left as it is)."""

    workers: int
    numba: int | None
    torch: int | None

    def apply(self) -> ThreadBudget:
        """Set this process's numba and torch thread counts (torch only if already imported)."""
        if self.numba is not None:
            import numba

            numba.set_num_threads(min(self.numba, numba.config.NUMBA_NUM_THREADS))
        torch = sys.modules.get("torch")
        if self.torch is not None and torch is not None:
            if torch.get_num_threads() != self.torch:
                torch.set_num_threads(self.torch)
        _APPLIED[:] = [self]
        return self

    def as_dict(self) -> dict:
        return asdict(self)


def applied_budget() -> ThreadBudget | None:
    """The budget this process applied last (None: none yet)."""
    return _APPLIED[0] if _APPLIED else None


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def trials_budget(threads: int, workers: int) -> ThreadBudget:
    """The budget of a trials process: ``threads`` numba threads per process (0: the cores shared
    out among the ``workers``, at least one each), torch one thread."""
    workers = max(1, workers)
    per_process = threads if threads > 0 else max(1, cores() // workers)
    return ThreadBudget(workers, per_process, TORCH_THREADS_BESIDE_NUMBA)


def torch_budget(threads: int) -> ThreadBudget:
    """The budget of a process that runs torch alone (meta-training, the accuracy study)."""
    return ThreadBudget(1, None, threads)
