"""One CPU kernel path for the recognisers: the same scores, so the same record bytes, on any
x86-64 machine.

torch chooses its CPU kernels by instruction set when a process first runs them, in three
libraries: ATen's own kernels (``ATEN_CPU_CAPABILITY``: default, avx2, avx512), oneDNN's
convolutions (``ONEDNN_MAX_CPU_ISA``) and MKL's matrix products (``MKL_CBWR``). Each path sums in
its own order, so the same Relation Network gives scores a few units in the last place apart on
two machines (docs/records.md "The schema"). :func:`pin_kernels` chooses
the path every x86-64 processor has (ATen ``default``, oneDNN ``SSE41``, MKL ``COMPATIBLE``)
before a recogniser is built; worker processes inherit it. It holds when no torch kernel ran in
the process before (each library reads its variable once, at its first kernel):
:func:`kernel_path` says which ATen path the process took, and the records keep it.
"""

from __future__ import annotations

import os

#: The variables that pin each library's kernels, and the value every x86-64 processor can run.
PINNED = {"ATEN_CPU_CAPABILITY": "default", "ONEDNN_MAX_CPU_ISA": "SSE41", "MKL_CBWR": "COMPATIBLE"}
#: The path meta-training pins: AVX2, which x86-64 processors have had since 2013. Training runs
#: its convolutions thousands of times, and the default path trains about 3.5 times slower (40
#: Relation Network episodes on 2 busy cores: 106 s, AVX2 30 s, AVX-512 unpinned 34 s); a
#: recogniser scores each picture once, so it keeps :data:`PINNED`.
TRAINING = {"ATEN_CPU_CAPABILITY": "avx2", "ONEDNN_MAX_CPU_ISA": "AVX2", "MKL_CBWR": "AVX2"}


def pin_kernels(path: dict[str, str] = PINNED) -> None:
    """Set ``path`` (:data:`PINNED` unless given) in this process's environment (and so in the
    workers it starts)."""
    os.environ.update(path)


def kernel_path() -> str:
    """ATen's kernel path in this process (``default`` once :func:`pin_kernels` took effect)."""
    import torch

    return torch.backends.cpu.get_cpu_capability().lower()
