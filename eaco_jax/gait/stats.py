"""Intervals for the rates a gait record reports."""

from __future__ import annotations


def falls_interval(falls: int, n: int) -> tuple[float, float]:
    """Exact (Clopper-Pearson) 95% interval of the fall rate from ``falls`` of ``n`` trials:
    a rate with its n, not a bare count, so 0 in 100 reads as "at most 3.6 %"."""
    from scipy.stats import beta

    lo = float(beta.ppf(0.025, falls, n - falls + 1)) if falls > 0 else 0.0
    hi = float(beta.ppf(0.975, falls + 1, n - falls)) if falls < n else 1.0
    return lo, hi


def fall_rate(falls: int, n: int) -> dict[str, object]:
    """``{"falls", "n", "fall_rate", "fall_rate_ci95"}``: a fall count as a record states it."""
    return {"falls": int(falls), "n": int(n), "fall_rate": int(falls) / max(int(n), 1),
            "fall_rate_ci95": list(falls_interval(int(falls), int(n)))}


__all__ = ["fall_rate", "falls_interval"]
