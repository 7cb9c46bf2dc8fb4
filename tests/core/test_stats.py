"""The verdict statistics: intervals that hold their level over few units, one-sided tests
that reject only what the data show, and the units a decision would need."""

import numpy as np
import pytest
from scipy import stats as sp

from macrostate_mj.core import stats
from macrostate_mj.core.errors import UserError


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


def test_the_nadeau_bengio_correction_matches_a_hand_computation():
    """Five folds of 325 instances (65 tested, 260 trained on): the corrected resampled t
    widens the plain interval by sqrt((1/5 + 65/260) / (1/5)) = 1.5, computed here by hand
    from the per-fold gains of chapter 2's 47 % claim: [26.8, 47.1] (the plain one [30.2, 43.7])."""
    gains = [28.275, 36.848, 37.852, 38.695, 43.212]
    mean = sum(gains) / 5
    s2 = sum((g - mean) ** 2 for g in gains) / 4          # the sample variance
    t4 = 2.7764451051977987                              # t(0.975, 4), from a table
    half = t4 * (s2 * (1 / 5 + 65 / 260)) ** 0.5
    assert stats.cv_ratio(5) == pytest.approx(65 / 260)
    pop = float(np.std(gains))
    lo, hi = stats.t_interval(mean, pop, 5, ratio=stats.cv_ratio(5))
    assert (lo, hi) == (pytest.approx(mean - half), pytest.approx(mean + half))
    assert (round(lo, 1), round(hi, 1)) == (26.8, 47.1)
    plain = stats.t_interval(mean, pop, 5)
    assert (round(plain[0], 1), round(plain[1], 1)) == (30.2, 43.7)
    assert (hi - lo) / (plain[1] - plain[0]) == pytest.approx(1.5)
    # the test and the counts use the same standard error
    se = (s2 * (1 / 5 + 0.25)) ** 0.5
    p = stats.p_above(mean - 40, pop, 5, ratio=0.25)
    assert p == pytest.approx(sp.t.sf((mean - 40) / se, 4))
    d = stats.paired_interval(gains, ratio=0.25)
    assert (d["low"], d["high"]) == (pytest.approx(lo), pytest.approx(hi))
    # more folds of the same overlap never shrink the error below sd * sqrt(ratio)
    assert stats.units_to_narrow(pop, 5, 0.9 * (s2 * 0.25) ** 0.5, ratio=0.25) is None
    with pytest.raises(UserError):
        stats.cv_ratio(1)


def test_the_two_level_bootstrap_holds_the_true_ratio_as_often_as_it_says():
    """Simulated sealed tests as the real one is made (45 instances whose difficulty both arms
    share, 4 model seeds whose spread is 4 % of the error, an arm 1.5x the reference): the
    95 % interval holds 1.5 in at least 93 % of 300 test sets."""
    from macrostate_mj.core.stats import two_level_bootstrap

    rng = np.random.default_rng(1)
    hits = 0
    for trial in range(300):
        inst = rng.gamma(4, 1.0, 45)
        ref = inst[None] + rng.normal(0, 0.15, (4, 1)) + rng.normal(0, 0.5, (4, 45))
        arm = 1.5 * inst[None] + rng.normal(0, 0.22, (4, 1)) + rng.normal(0, 0.7, (4, 45))
        ratio = two_level_bootstrap(arm, ref, draws=600, seed=trial)["ratio"]
        hits += ratio["low"] <= 1.5 <= ratio["high"]
    assert hits / 300 >= 0.93
