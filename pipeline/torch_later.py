"""torch's settings in this process, answered before torch is imported, and importing it with
them: a recogniser that starts from its score file (:mod:`pipeline.fewshot.from_files`) records the
thread count and kernel path its scores are computed with, and imports torch only at its first
column not in the file (about 2 s on this machine), if ever.
"""

from __future__ import annotations

import os
import sys

from pipeline import kernels
from pipeline.threads import applied_budget


def import_torch():
    """torch, imported now if it was not, with the torch share of the budget this process applied
    (the share :meth:`pipeline.threads.ThreadBudget.apply` could not give it before)."""
    import torch

    budget = applied_budget()
    if budget is not None and budget.torch is not None and torch.get_num_threads() != budget.torch:
        torch.set_num_threads(budget.torch)
    return torch


def torch_threads() -> int:
    """torch's intra-op threads: torch's own count once imported, else the share of the budget
    applied (what :func:`import_torch` will give it), else torch's count (importing it)."""
    budget = applied_budget()
    if "torch" not in sys.modules and budget is not None and budget.torch is not None:
        return budget.torch
    return import_torch().get_num_threads()


def kernel_path() -> str:
    """ATen's kernel path (:func:`pipeline.kernels.kernel_path`). Before torch is imported, a
    pinned ``default`` is the path it will take (it reads the variable at its first kernel, and
    every x86-64 processor runs it), so asking then does not import torch."""
    pinned = kernels.PINNED["ATEN_CPU_CAPABILITY"]
    if "torch" not in sys.modules and os.environ.get("ATEN_CPU_CAPABILITY") == pinned:
        return pinned
    return kernels.kernel_path()
