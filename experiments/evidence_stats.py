"""Statistics of the evidence experiments: CIs, paired tests, success statistics.

* :func:`bootstrap_ci` - percentile bootstrap CI of the mean (seeded, 10,000 resamples).
* :func:`t_ci` - Student-t CI of the mean.
* :func:`paired_test` - Wilcoxon signed-rank test on seed-paired runs (scipy; exact for
  small samples without ties, normal approximation otherwise); identical samples give p = 1.
* :func:`holm` - Holm-Bonferroni adjusted p-values for a family of comparisons.
* :func:`success_performance` - CEC2006 SP = mean evaluations of successful runs x runs /
  successes; and the premature-convergence estimate (fraction stuck above target).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def bootstrap_ci(x: Sequence[float], level: float = 0.95, resamples: int = 10_000,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of the mean of ``x`` (finite values only)."""
    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return (math.nan, math.nan)
    if a.size == 1 or np.all(a == a[0]):
        return (float(a[0]), float(a[0])) if a.size else (math.nan, math.nan)
    rng = np.random.default_rng(seed)
    means = a[rng.integers(0, a.size, (resamples, a.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def t_ci(x: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """Student-t CI of the mean."""
    from scipy import stats

    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    if a.size < 2:
        return (math.nan, math.nan)
    half = stats.t.ppf((1 + level) / 2, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size)
    return float(a.mean() - half), float(a.mean() + half)


def paired_test(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided Wilcoxon signed-rank p-value for seed-paired samples ``a`` and ``b``.

    Infinite values (a run that never reached a feasible point / the target) are replaced by
    a value above every finite one in the pair, so they rank as the worst; all-zero
    differences give p = 1.
    """
    from scipy import stats

    x, y = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if x.shape != y.shape:
        raise ValueError(f"paired samples differ in length: {x.shape} vs {y.shape}")
    both = np.concatenate([x, y])
    finite = both[np.isfinite(both)]
    worst = (finite.max() + 1.0 + abs(finite.max())) if finite.size else 1.0
    x, y = np.where(np.isfinite(x), x, worst), np.where(np.isfinite(y), y, worst)
    d = x - y
    if np.all(d == 0):
        return 1.0
    return float(stats.wilcoxon(x, y, zero_method="wilcox").pvalue)


def holm(p: Sequence[float]) -> list[float]:
    """Holm-Bonferroni adjusted p-values (same order as ``p``)."""
    p = np.asarray(p, np.float64)
    order = np.argsort(p)
    m = p.size
    adjusted = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adjusted[i] = running
    return adjusted.tolist()


def summary(x: Sequence[float]) -> dict[str, float]:
    """mean, bootstrap 95 % CI, median, min, max of the finite values, and how many are not."""
    a = np.asarray(x, np.float64)
    f = a[np.isfinite(a)]
    lo, hi = bootstrap_ci(f)
    nan = math.nan
    return {"mean": float(f.mean()) if f.size else nan, "ci_low": lo, "ci_high": hi,
            "median": float(np.median(f)) if f.size else nan,
            "min": float(f.min()) if f.size else nan, "max": float(f.max()) if f.size else nan,
            "n": int(a.size), "non_finite": int(a.size - f.size)}


def success_performance(evals_to_target: Sequence[float]) -> float | None:
    """CEC2006 SP: mean evaluations of the successful runs x runs / successes (None if none).
    Unsuccessful runs are negative or non-finite entries."""
    e = np.asarray(evals_to_target, np.float64)
    ok = np.isfinite(e) & (e >= 0)
    if not ok.any():
        return None
    return float(e[ok].mean() * e.size / ok.sum())


def stuck_fraction(final: Sequence[float], target: float) -> float:
    """Premature-convergence estimate: the fraction of runs above ``target`` at the budget."""
    f = np.asarray(final, np.float64)
    return float(np.mean(~(f <= target)))
