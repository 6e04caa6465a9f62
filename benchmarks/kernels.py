"""Scores on each CPU kernel path: how far apart torch's instruction-set paths put the recognisers'
scores, and that the one path of ``pipeline/kernels.py`` puts them nowhere apart.

    python -m benchmarks.kernels [--columns 600] [--images datasets/images]

Each setting runs in a child process (a kernel path is chosen once per process): it builds the
Relation Network and the Prototypical Network from ``datasets/models`` and scores ``--columns``
random support states (5 members each) of the 40 query pictures. Unpinned settings restrict one
library's instruction set at a time (ATen, oneDNN, MKL) and are compared with the native path;
pinned settings add ``pipeline.kernels.PINNED`` and restrict what it leaves free (MKL's dispatch,
glibc's FMA variants) and are compared with the pinned path. Prints the largest difference in
units in the last place (ulp) and the share of scores that differ, and the seconds per column;
writes reports/benchmarks/kernels.json.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks._output import write_figures
from pipeline.kernels import PINNED

#: Setting name -> environment (``pinned`` ones get PINNED too).
UNPINNED = {
    "native": {},
    "aten_default": {"ATEN_CPU_CAPABILITY": "default"},
    "aten_avx2": {"ATEN_CPU_CAPABILITY": "avx2"},
    "onednn_avx2": {"ONEDNN_MAX_CPU_ISA": "AVX2"},
    "onednn_sse41": {"ONEDNN_MAX_CPU_ISA": "SSE41"},
    "mkl_avx2": {"MKL_ENABLE_INSTRUCTIONS": "AVX2"},
    "mkl_sse42": {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"},
}
PINNED_SETTINGS = {
    "pinned": {},
    "pinned_mkl_sse42": {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"},
    "pinned_glibc_no_fma": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"},
}
MODELS = {
    "relation_net": "datasets/models/relation_net.pt",
    "protonet": "datasets/models/protonet.pt",
}


def child(out: str, columns: int, images: str) -> None:
    """In the child: every model's scores of ``columns`` random support states, and the seconds."""
    import torch

    from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser, softmax_rows

    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    saved = {}
    for kind, cls in (("relation_net", RelationRecogniser), ("protonet", ProtoRecogniser)):
        rec = cls.from_files(MODELS[kind], images)
        codes = np.array(sorted(rec.parts))
        start = time.perf_counter()
        with torch.no_grad():
            table = np.stack([rec.forward(parts(rec, codes, rng)) for _ in range(columns)], axis=1)
        saved[f"{kind}_seconds"] = np.array((time.perf_counter() - start) / columns)
        if kind == "protonet":  # its scores are the softmax of a row of five columns
            table = np.concatenate(
                [softmax_rows(table[:, j : j + 5]) for j in range(0, columns - 4, 5)], axis=1
            )
        saved[kind] = table.astype(np.float32)
    saved["aten"] = np.array(torch.backends.cpu.get_cpu_capability())
    np.savez(out, **saved)


def parts(rec, codes, rng):
    """The stacked parts of 5 random members of ``codes`` (a category's support members)."""
    import torch

    return torch.stack([rec.parts[int(m)] for m in np.sort(rng.choice(codes, 5, replace=False))])


def ulp(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a.view(np.int32).astype(np.int64) - b.view(np.int32).astype(np.int64))


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--columns", type=int, default=600)
    ap.add_argument("--images", default="datasets/images")
    ap.add_argument("--json", default="reports/benchmarks/kernels.json")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.columns, args.images)
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        settings = {**UNPINNED, **{k: {**PINNED, **v} for k, v in PINNED_SETTINGS.items()}}
        for name, env in settings.items():
            out = f"{tmp}/{name}.npz"
            clean = {k: v for k, v in os.environ.items() if k not in PINNED}
            subprocess.run(
                [sys.executable, "-m", "benchmarks.kernels", "--child", out]
                + ["--columns", str(args.columns), "--images", args.images],
                env={**clean, **env},
                check=True,
            )
            runs[name] = dict(np.load(out))
    figures = {"columns": args.columns, "cpu": _cpu(), "settings": {}}
    for name in settings:
        base = runs["pinned" if name.startswith("pinned") else "native"]
        row = {"aten": str(runs[name]["aten"])}
        for kind in MODELS:
            d = ulp(base[kind], runs[name][kind])
            row[kind] = {
                "max_ulp": int(d.max()),
                "share_differing": round(float((d > 0).mean()), 3),
                "ms_per_column": round(1000 * float(runs[name][f"{kind}_seconds"]), 2),
            }
        figures["settings"][name] = row
        print(
            f"{name:22s} vs {'pinned' if name.startswith('pinned') else 'native':6s} "
            + "  ".join(
                f"{k}: max {row[k]['max_ulp']:3d} ulp, {100 * row[k]['share_differing']:4.1f}% "
                f"differ, {row[k]['ms_per_column']:.2f} ms/column"
                for k in MODELS
            )
        )
    write_figures(args.json, figures, "benchmarks.kernels")


def _cpu() -> str:
    try:
        line = next(x for x in Path("/proc/cpuinfo").read_text().splitlines() if "model name" in x)
        return line.split(":", 1)[1].strip()
    except (OSError, StopIteration):
        return "unknown"


if __name__ == "__main__":
    main()
