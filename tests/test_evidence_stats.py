"""The statistics of experiments/common.py on cases with known answers."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

PATH = Path(__file__).resolve().parent.parent / "experiments" / "common.py"


@pytest.fixture(scope="module")
def st():
    spec = importlib.util.spec_from_file_location("common", PATH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_paired_test_detects_a_shift_and_not_noise(st):
    rng = np.random.default_rng(0)
    a = rng.normal(0, 1, 25)
    assert st.paired_test(a, a + 1.0) < 1e-4  # every pair differs the same way
    assert st.paired_test(a, a) == 1.0
    b = a + rng.normal(0, 1e-3, 25) * np.where(np.arange(25) % 2, 1, -1)
    assert st.paired_test(a, b) > 0.05
    # exact small-sample value: 6 pairs all positive -> two-sided p = 2 / 2^6
    np.testing.assert_allclose(st.paired_test(np.arange(6) + 1.0, np.zeros(6)), 2 / 64)
    # a failed run (inf) ranks as the worst
    assert st.paired_test([1, 2, 3, 4, 5, 6], [np.inf] * 6) < 0.05


def test_cis_cover_the_mean_and_shrink_with_n(st):
    rng = np.random.default_rng(1)
    small, large = rng.normal(5, 1, 25), rng.normal(5, 1, 400)
    for x in (small, large):
        lo, hi = st.bootstrap_ci(x)
        assert lo < x.mean() < hi
        tlo, thi = st.t_ci(x)
        assert abs((hi - lo) - (thi - tlo)) < 0.25 * (thi - tlo)
    assert np.diff(st.bootstrap_ci(large)) < np.diff(st.bootstrap_ci(small))


def test_holm_and_success_statistics(st):
    np.testing.assert_allclose(st.holm([0.01, 0.04, 0.03]), [0.03, 0.06, 0.06])
    assert st.success_performance([100, 200, -1, -1]) == 150 * 4 / 2
    assert st.success_performance([-1, -1]) is None
    assert st.stuck_fraction([1.0, 2.0, 3.0, np.inf], 2.0) == 0.5
