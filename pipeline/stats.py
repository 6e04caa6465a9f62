"""Summary statistics of the report and of the trials' metrics files (:mod:`pipeline.cells.metrics`):
mean, standard deviation and a seeded 95% bootstrap interval of the mean (tables); per-episode
means with a 95% t interval (the bands of learning curves); bootstrap intervals of differences
between cells (the claims) and of break-even levels (:func:`break_even`); Wilson intervals of
shares of runs; stratified bootstrap over the accuracy study's random draws (Tables 1 and 2:
:func:`stratified_means`); a cluster (two-level) bootstrap for data that vary at two levels
(:func:`cluster_ratio_draws`: meta-test families then episodes, obstacles then views); bootstrap
p-values (:func:`bootstrap_p`) and Holm's step-down correction across the checks of a claim
(:func:`holm`) and across the claims (:func:`holm_adjusted`).

The independent unit of a trial is its run seed: the cells of an experiment (and the experiments
recorded with the same seed and run count) share run ``r``'s obstacle placement and random
streams, so a row that pools cells resamples run seeds (``clusters``), and a difference between
cells is bootstrapped over run seeds, pairing run ``r`` of one cell with run ``r`` of the other."""

from __future__ import annotations

import warnings

import numpy as np


def bootstrap_ci(
    values, *, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean (seeded: the same data give the same interval)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return (float("nan"), float("nan"))
    if v.size == 1:
        return (float(v[0]), float(v[0]))
    return percentile_ci(bootstrap_means(v, resamples=resamples, seed=seed), level)


def bootstrap_means(values, *, resamples: int = 2000, seed: int = 0) -> np.ndarray:
    """The means of ``resamples`` resamples of ``values`` with replacement (seeded)."""
    v = np.asarray(values, dtype=float)
    rng = np.random.default_rng(seed)
    return v[rng.integers(0, v.size, size=(resamples, v.size))].mean(axis=1)


def stratified_means(values, *, resamples: int = 2000, seed: int = 0) -> np.ndarray:
    """Bootstrap means of ``values`` (strata x draws, one row per stratum: the accuracy study's
    substituted categories, each with its own ``repeats`` independent draws), resampling draws
    within each stratum, so every resample keeps the design's draws per stratum (seeded)."""
    v = np.atleast_2d(np.asarray(values, dtype=float))
    rng = np.random.default_rng(seed)
    index = rng.integers(0, v.shape[1], size=(resamples, *v.shape))
    return np.take_along_axis(v[None], index, axis=2).mean(axis=(1, 2))


def cluster_ratio_draws(
    numerators,
    denominators,
    clusters,
    *,
    within: bool,
    resamples: int = 2000,
    seed=0,
    block: int = 250,
) -> np.ndarray:
    """Bootstrap draws of ``sum(numerators) / sum(denominators)`` (a pooled share: correct over
    tested) resampled at the level the data vary, for units (rows) grouped in ``clusters`` (one id
    per row).

    Each draw takes as many clusters as there are, uniformly with replacement (stage 1); a cluster
    drawn twice counts twice. With ``within`` (stage 2, a two-level bootstrap), each drawn cluster
    then brings as many of its own units as it has, uniformly with replacement; without, it
    brings all its units as they are (one-level cluster bootstrap). Davison and Hinkley (1997,
    section 3.8): resampling both stages counts the within-cluster variance once more, so the
    two-level interval errs wide by about that variance over the cluster's size (small where the
    clusters are many units each). Stage 1 uses ``numpy.random.default_rng(seed)``, stage 2 a
    stream spawned from the same seed, so the clusters drawn do not depend on ``within``; without
    it, for clusters of equal size, the draws equal :func:`bootstrap_means` of the cluster means
    with the same seed. ``block`` resamples are drawn at a time (memory), which changes no draw."""
    num = np.asarray(numerators, dtype=float)
    den = np.asarray(denominators, dtype=float)
    ids, index = np.unique(np.asarray(clusters), return_inverse=True)
    k = ids.size
    if num.shape != den.shape or num.shape != index.shape or k == 0:
        raise ValueError(
            f"numerators {num.shape}, denominators {den.shape} and clusters {index.shape} must be "
            "non-empty and of one length"
        )
    sizes = np.bincount(index, minlength=k)
    order = np.argsort(index, kind="stable")
    within_at = np.arange(index.size) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    padded = np.zeros((2, k, int(sizes.max())))
    padded[0, index[order], within_at], padded[1, index[order], within_at] = num[order], den[order]
    clusters_rng = np.random.default_rng(seed)
    units_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    out = []
    for start in range(0, resamples, block):
        picked = clusters_rng.integers(0, k, size=(min(block, resamples - start), k))
        if within:
            n = sizes[picked][..., None]  # (b, k, 1): each drawn cluster's size
            unit = (units_rng.random((*picked.shape, padded.shape[2])) * n).astype(np.int64)
            keep = np.arange(padded.shape[2]) < n
            sums = np.where(keep, padded[:, picked[..., None], unit], 0.0).sum(axis=(2, 3))
        else:
            sums = padded[:, picked].sum(axis=(2, 3))
        out.append(sums[0] / sums[1])
    return np.concatenate(out)


def percentile_ci(draws, level: float = 0.95) -> tuple[float, float]:
    """The percentile interval of bootstrap ``draws`` of a statistic."""
    lo, hi = np.quantile(np.asarray(draws, dtype=float), [(1 - level) / 2, 1 - (1 - level) / 2])
    return (float(lo), float(hi))


def bootstrap_p(draws, null: float = 0.0) -> float:
    """Two-sided bootstrap p-value of ``null`` for a statistic with bootstrap ``draws``: twice the
    smaller share of draws on either side of it (each share counted as ``(k + 1) / (B + 1)``), so
    ``p <= a`` where the percentile interval at level ``1 - a`` excludes ``null``."""
    d = np.asarray(draws, dtype=float)
    below, above = np.sum(d <= null), np.sum(d >= null)
    return float(min(1.0, 2 * (min(below, above) + 1) / (d.size + 1)))


def holm(pvalues, level: float = 0.05) -> tuple[list[float], list[bool]]:
    """Holm's step-down correction (Holm 1979) of ``m`` tests: sorted by p-value, the ``i``-th
    smallest (from 0) is rejected when ``p <= level / (m - i)`` and every smaller one was; the family
    errs with probability at most ``level``. Returns each test's threshold and whether it is
    rejected, in the given order."""
    p = np.asarray(pvalues, dtype=float)
    thresholds, rejected = [0.0] * p.size, [False] * p.size
    going = True
    for i, k in enumerate(np.argsort(p, kind="stable")):
        thresholds[k] = level / (p.size - i)
        going = going and bool(p[k] <= thresholds[k])
        rejected[k] = going
    return thresholds, rejected


def holm_adjusted(pvalues) -> list[float]:
    """Holm's adjusted p-values (Holm 1979; Wright 1992): sorted, the ``i``-th smallest (from 0) of
    ``m`` becomes ``max_{j <= i} min(1, (m - j) p_(j))``, so a test is rejected by :func:`holm` at
    ``level`` exactly when its adjusted p-value is at most ``level``. In the given order."""
    p = np.asarray(pvalues, dtype=float)
    out, running = [0.0] * p.size, 0.0
    for i, k in enumerate(np.argsort(p, kind="stable")):
        running = max(running, min(1.0, float((p.size - i) * p[k])))
        out[k] = running
    return out


def cluster_means(values, clusters) -> np.ndarray:
    """The mean of ``values`` per cluster id (in the order of the sorted ids)."""
    ids, index = np.unique(np.asarray(clusters), return_inverse=True)
    v = np.asarray(values, dtype=float)
    return np.bincount(index, weights=v, minlength=ids.size) / np.bincount(
        index, minlength=ids.size
    )


def describe(values, clusters=None) -> dict:
    """Mean, s.d. (of the values) and 95% bootstrap CI of the mean; with ``clusters`` (one id per
    value, e.g. the run seed of each pooled run) the CI resamples clusters, not values."""
    v = np.asarray(values, dtype=float)
    lo, hi = bootstrap_ci(v if clusters is None else cluster_means(v, clusters))
    return {
        "n": int(v.size),
        "mean": float(v.mean()) if v.size else float("nan"),
        "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
        "ci_low": lo,
        "ci_high": hi,
    }


def fmt(d: dict, digits: int = 2) -> str:
    """``mean ± std [lo, hi]`` for tables."""
    return f"{d['mean']:.{digits}f} ± {d['std']:.{digits}f} [{d['ci_low']:.{digits}f}, {d['ci_high']:.{digits}f}]"


#: The standard normal's 0.975 quantile.
Z975 = 1.959963984540054

#: Student's t 0.975 quantiles for 1-10 degrees of freedom; beyond, the Cornish-Fisher expansion
#: (:func:`t_quantile_975`) is within 0.01% of the exact value.
_T975 = (12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622, 2.2281)


def t_quantile_975(df: int) -> float:
    """The 0.975 quantile of Student's t with ``df`` degrees of freedom (no scipy needed)."""
    if df < 1:
        return float("nan")
    if df <= len(_T975):
        return _T975[df - 1]
    z = 1.959963984540054
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160
    return z + g1 / df + g2 / df**2 + g3 / df**3 + g4 / df**4


def mean_band(values) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of ``values`` (runs x episodes; NaN = no such episode): the mean over runs and
    its 95% Student-t interval (mean ± t * s.d. / sqrt(n)); the interval is the mean where n < 2.
    A t interval rather than the bootstrap of :func:`describe`: one per episode of every curve."""
    v = np.atleast_2d(np.asarray(values, dtype=float))
    n = np.sum(~np.isnan(v), axis=0)
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # an episode no run reached: NaN
        mean = np.nanmean(v, axis=0) if v.size else np.zeros(v.shape[1])
        sd = np.nanstd(v, axis=0, ddof=1) if v.shape[0] > 1 else np.zeros(v.shape[1])
        half = (
            np.array([t_quantile_975(int(k) - 1) if k > 1 else 0.0 for k in n])
            * np.nan_to_num(sd)
            / np.sqrt(np.maximum(n, 1))
        )
    return mean, mean - half, mean + half


def bootstrap_difference(
    a, b, *, paired: bool, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> tuple[float, float, float]:
    """``mean(a) - mean(b)`` and its percentile-bootstrap interval. ``paired``: ``a[i]`` and
    ``b[i]`` come from one run seed (resample seeds, the differences' mean); else the two are
    resampled independently."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    draws = difference_draws(a, b, paired=paired, resamples=resamples, seed=seed)
    return (float(a.mean() - b.mean()), *percentile_ci(draws, level))


def difference_draws(a, b, *, paired: bool, resamples: int = 2000, seed: int = 0) -> np.ndarray:
    """Bootstrap draws of ``mean(a) - mean(b)`` (:func:`bootstrap_difference`'s resamples)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if paired:
        return bootstrap_means(a - b, resamples=resamples, seed=seed)
    rng = np.random.default_rng(seed)
    means = [x[rng.integers(0, x.size, size=(resamples, x.size))].mean(axis=1) for x in (a, b)]
    return means[0] - means[1]


def break_even(
    levels, curve, reference, *, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> tuple[float, float, float]:
    """The break-even level of a curve against a reference, and its percentile-bootstrap interval.

    ``levels`` (k, increasing) are the settings of the curve's points; ``curve`` (k x runs) holds
    each point's values per run, ``reference`` (runs) the reference's. The break-even level is the
    smallest level whose mean over runs is at or below the reference's mean; ``inf`` if none is.
    Run ``i`` of every point and of the reference share a run seed, so each of the ``resamples``
    draws one set of run indices for all of them (paired), and the break-even level of the
    resampled means is found the same way. The interval's ends are order statistics of those
    levels (the ``(1-level)/2`` and ``(1+level)/2`` quantiles, lower and upper: values of the grid
    or ``inf``), so its resolution is the grid's."""
    levels = np.asarray(levels, dtype=float)
    c, r = np.asarray(curve, dtype=float), np.asarray(reference, dtype=float)

    def first(means: np.ndarray, ref: np.ndarray) -> np.ndarray:  # (k, b), (b,) -> (b,)
        at_or_below = means <= ref
        return np.where(at_or_below.any(axis=0), levels[np.argmax(at_or_below, axis=0)], np.inf)

    point = float(first(c.mean(axis=1)[:, None], np.array([r.mean()]))[0])
    rng = np.random.default_rng(seed)
    index = rng.integers(0, r.size, size=(resamples, r.size))
    levels_drawn = np.sort(first(c[:, index].mean(axis=2), r[index].mean(axis=1)))
    low = levels_drawn[int(np.floor((1 - level) / 2 * resamples))]
    high = levels_drawn[int(np.ceil((1 + level) / 2 * resamples)) - 1]
    return point, float(low), float(high)


def wilson_ci(share: float, n: int) -> tuple[float, float]:
    """95% score (Wilson) interval of a share of ``n`` independent yes/no outcomes (converged runs)."""
    if n < 1:
        return (float("nan"), float("nan"))
    z = Z975
    centre = (share + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * np.sqrt(share * (1 - share) / n + z * z / (4 * n * n))
    return (float(max(centre - half, 0.0)), float(min(centre + half, 1.0)))
