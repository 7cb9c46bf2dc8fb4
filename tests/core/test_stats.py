"""The verdict statistics: intervals that hold their level over few units, one-sided tests
that reject only what the data show, and the units a decision would need."""

import numpy as np
import pytest
from scipy import stats as sp

from macrostate_mj.core import stats


def test_t_interval_holds_its_level_where_a_percentile_bootstrap_does_not():
    """Why the claims use t: over 3 or 5 units a 95 % percentile bootstrap misses the mean far
    more often than 5 % of the time (the reproduction index says so), t's does not."""
    rng = np.random.default_rng(0)
    for n, bootstrap_at_most in ((3, 0.85), (5, 0.9)):
        hits_t = hits_boot = 0
        for _ in range(600):
            x = rng.normal(0.0, 1.0, n)
            lo, hi = stats.t_interval(float(x.mean()), float(x.std()), n)
            hits_t += lo <= 0 <= hi
            means = rng.choice(x, (1000, n)).mean(axis=1)
            b_lo, b_hi = np.percentile(means, [2.5, 97.5])
            hits_boot += b_lo <= 0 <= b_hi
        assert hits_t / 600 > 0.92 and hits_boot / 600 < bootstrap_at_most, (n, hits_t, hits_boot)


def test_the_interval_and_tests_match_scipy_on_raw_values():
    x = np.array([1.2, 0.4, 2.1, 1.7, 0.9])
    lo, hi = stats.t_interval(float(x.mean()), float(x.std()), len(x))
    ref = sp.ttest_1samp(x, 0.0).confidence_interval(0.95)
    assert (lo, hi) == pytest.approx((ref.low, ref.high))
    p = stats.p_above(float(x.mean()), float(x.std()), len(x))
    assert p == pytest.approx(sp.ttest_1samp(x, 0.0, alternative="greater").pvalue)
    y = np.array([0.1, 0.5, -0.2, 0.3])
    p_w = stats.p_above_welch((x.mean(), x.std(), 5), (y.mean(), y.std(), 4))
    assert p_w == pytest.approx(sp.ttest_ind(x, y, equal_var=False,
                                             alternative="greater").pvalue)


def test_one_unit_decides_nothing():
    assert stats.t_interval(3.0, 0.0, 1) is None
    assert stats.p_above(3.0, 0.0, 1) is None
    assert stats.p_above_welch((3.0, 0.0, 1), (1.0, 0.5, 5)) is None
    assert stats.units_to_decide(1.0, 0.5, 1) is None


def test_units_to_decide_is_the_first_count_at_which_the_test_rejects():
    """At the observed mean and spread, n - 1 units would not reject and n would."""
    mean, std, n = 0.4, 1.0, 5
    need = stats.units_to_decide(mean, std, n)
    sd = std * (n / (n - 1)) ** 0.5
    t_at = [mean / (sd / m ** 0.5) > sp.t.ppf(0.95, m - 1) for m in (need - 1, need)]
    assert t_at == [False, True] and need > n
    assert stats.units_to_decide(0.0, 1.0, 5) is None


def test_units_to_narrow_is_the_first_count_whose_interval_fits():
    std, n, half = 1.0, 5, 0.5
    need = stats.units_to_narrow(std, n, half)
    sd = std * (n / (n - 1)) ** 0.5
    widths = [sp.t.ppf(0.975, m - 1) * sd / m ** 0.5 for m in (need - 1, need)]
    assert widths[0] > half >= widths[1]
    assert stats.units_to_narrow(std, 1, half) is None


def test_a_zero_crossing_recovers_its_line_and_its_interval_holds_its_level():
    """Points scattered about y = 0.5 (x - 0.6): the crossing is read near 0.6, and over many
    such sets its 95 % interval holds 0.6 about 95 % of the time (Fieller's is exact here);
    a flat cloud has no bounded crossing; fewer than 3 points are refused."""
    rng = np.random.default_rng(1)
    x = np.linspace(0.8, 2.0, 11)
    got = stats.zero_crossing(list(x), list(0.5 * (x - 0.6) + rng.normal(0, 0.05, x.size)))
    assert got["x"] == pytest.approx(0.6, abs=0.1) and got["n"] == 11 and got["r"] > 0.9
    held = 0
    for _ in range(2000):
        c = stats.zero_crossing(list(x), list(0.5 * (x - 0.6) + rng.normal(0, 0.1, x.size)))
        held += c["low"] is not None and c["low"] <= 0.6 <= c["high"]
    assert 0.93 <= held / 2000 <= 0.97
    flat = stats.zero_crossing(list(x), list(rng.normal(0, 1, x.size)))
    assert flat["low"] is None or flat["high"] - flat["low"] > 1
    with pytest.raises(ValueError, match="3 points"):
        stats.zero_crossing([1.0, 2.0], [0.1, 0.2])
    for xs, ys in (([1.0, 2.0, 3.0], [0.1, 0.2]), ([1.0, 2.0, float("nan")], [0.1, 0.2, 0.3])):
        with pytest.raises(ValueError, match="as many finite y as x"):
            stats.zero_crossing(xs, ys)
