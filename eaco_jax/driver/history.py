"""A run's history: per-iteration metrics, recorded chunk by chunk and merged once."""

from __future__ import annotations

from typing import Any

import numpy as np


def merge_history(history: list[dict[str, Any]], axis: int) -> dict[str, np.ndarray]:
    """Concatenate per-chunk history dicts along the iteration axis (1 with a row axis)."""
    if not history:
        return {}
    return {
        k: np.concatenate([np.asarray(h[k]) for h in history], axis=axis) for k in history[0]
    }
