"""Summary statistics for the report: mean, standard deviation and a seeded 95% bootstrap interval."""
from __future__ import annotations

import numpy as np


def bootstrap_ci(values, *, level: float = 0.95, resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean (seeded: the same data give the same interval)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return (float("nan"), float("nan"))
    if v.size == 1:
        return (float(v[0]), float(v[0]))
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, v.size, size=(resamples, v.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, 1 - (1 - level) / 2])
    return (float(lo), float(hi))


def describe(values) -> dict:
    v = np.asarray(values, dtype=float)
    lo, hi = bootstrap_ci(v)
    return {"n": int(v.size), "mean": float(v.mean()) if v.size else float("nan"),
            "std": float(v.std(ddof=1)) if v.size > 1 else 0.0, "ci_low": lo, "ci_high": hi}


def fmt(d: dict, digits: int = 2) -> str:
    """``mean ± std [lo, hi]`` for tables."""
    return f"{d['mean']:.{digits}f} ± {d['std']:.{digits}f} [{d['ci_low']:.{digits}f}, {d['ci_high']:.{digits}f}]"
