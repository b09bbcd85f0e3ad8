"""Tail probabilities (vectorised continued fractions) against mpmath, at the tails and for the
degrees of freedom of large datasets; they terminate on NaN and infinity."""
import math

import mpmath
import numpy as np
import pytest

from handeye.model.common.statistics import chi2_survival, chi2_survival_array, f_survival, f_survival_array


def _f_reference(x, d1, d2):
    if d2 > 10_000:  # mpmath's series does not converge there; d1 F tends to chi^2_d1 (error O(1/d2))
        return float(mpmath.gammainc(d1 / 2, d1 * x / 2, mpmath.inf, regularized=True))
    z = d2 / (d2 + d1 * x)
    return float(mpmath.betainc(d2 / 2, d1 / 2, 0, z, regularized=True))


@pytest.mark.parametrize("d1,d2", [(3, 1), (3, 2), (3, 7), (3, 30), (3, 200), (1, 5), (2, 40), (6, 9), (3, 600_000)])
def test_f_survival_against_mpmath(d1, d2):
    rng = np.random.default_rng(d1 * 1000 + d2)
    xs = np.concatenate([[1e-12, 0.1, 1.0, 3.0, 10.0, 50.0, 200.0, 1e4, 1e8], rng.uniform(0, 20, 20)])
    got = f_survival_array(xs, d1, d2)
    rel = 1e-9 if d2 <= 10_000 else 1e-3 * (1 + xs)  # the chi-square limit's own error grows in the tail
    for x, g, r in zip(xs, got, np.broadcast_to(rel, xs.shape)):
        if d2 > 10_000 and x > 100:
            continue  # far tail: limit and F differ by more than O(1/d2); mpmath gives neither
        ref = _f_reference(x, d1, d2)
        assert g == pytest.approx(ref, rel=r, abs=1e-300), (x, d1, d2)
    assert f_survival(2.0, d1, d2) == pytest.approx(_f_reference(2.0, d1, d2), rel=1e-9 if d2 <= 10_000 else 1e-3)


@pytest.mark.parametrize("k", [1, 2, 3, 4, 6, 9, 30, 200])
def test_chi2_survival_against_mpmath(k):
    xs = np.array([1e-9, 0.5, 1.0, 3.0, 10.0, 50.0, 200.0, 1000.0, 5000.0])
    got = chi2_survival_array(xs, k)
    for x, g in zip(xs, got):
        ref = float(mpmath.gammainc(k / 2, x / 2, mpmath.inf, regularized=True))
        assert g == pytest.approx(ref, rel=1e-9, abs=1e-300), (x, k)


def test_edges_terminate():
    assert math.isnan(f_survival(math.nan, 3, 7)) and f_survival(math.inf, 3, 7) == 0.0 and f_survival(0, 3, 7) == 1.0
    assert math.isnan(chi2_survival(math.nan, 3)) and chi2_survival(math.inf, 3) == 0.0 and chi2_survival(0, 3) == 1.0
    assert math.isnan(f_survival(1.0, 3, 0))


@pytest.mark.parametrize("a", [0.5, 1.0, 1.5, 2.5, 4.5, 15.0, 100.0, 1e3, 3e4, 3e5, 1.5e6])
def test_gamma_tail_against_scipy_from_the_bulk_to_the_far_tail(a):
    """Q(a, x) over x from 1e-6 a to 20 a and a +- 37 sqrt(a) (tails down to 1e-290), a up to
    1.5e6 (chi-square with 3 million degrees of freedom: a million measurements)."""
    special = pytest.importorskip("scipy.special")
    from handeye.model.common.statistics import _gammainc_upper

    xs = np.concatenate([a * np.array([1e-6, 0.01, 0.5, 0.9, 0.99, 1.0, 1.01, 1.1, 2.0, 5.0, 20.0]),
                         a + np.sqrt(a) * np.array([-8, -3, -1, -0.1, 0.1, 1, 3, 8, 20, 37])])
    xs = xs[xs > 0]
    ref = special.gammaincc(a, xs)
    got = _gammainc_upper(a, xs)
    tiny = ref < 1e-300  # below the double range scipy's value is 0 as well
    assert np.all(got[tiny] < 1e-290)
    assert np.allclose(got[~tiny], ref[~tiny], rtol=1e-11, atol=0), (a, np.max(np.abs(got - ref) / ref))


def test_tails_of_a_million_statistics_against_scipy():
    """The whole-array path (tiny p included): chi-square 3 and F(3, d2) for d2 on both sides of
    F_AS_CHI2_ABOVE, and the Bonferroni-adjusted tails computed only where they can matter."""
    stats = pytest.importorskip("scipy.stats")
    from handeye.model.common.statistics import bonferroni_survival

    rng = np.random.default_rng(7)
    x = np.concatenate([rng.chisquare(3, 200_000), [1e-12, 40.0, 80.0, 150.0, 600.0, 1400.0]])
    ref = stats.chi2.sf(x, 3)
    assert np.allclose(chi2_survival_array(x, 3), ref, rtol=1e-11, atol=1e-300)
    assert ref[-1] < 1e-290  # the far tail is in the grid
    for d2 in (50.0, 9_000.0):
        assert np.allclose(f_survival_array(x / 3, 3, d2), stats.f.sf(x / 3, 3, d2), rtol=1e-9, atol=1e-300)
    n = len(x)
    adjusted = bonferroni_survival(x, n, 3)
    assert np.allclose(adjusted, np.minimum(ref * n, 1.0), rtol=1e-11, atol=1e-300)
    d2 = np.where(np.arange(n) % 2, 2_999_991.0, 2_999_994.0)
    adjusted = bonferroni_survival(x / 3, n, 3, d2)
    assert np.allclose(adjusted, np.minimum(f_survival_array(x / 3, 3, d2) * n, 1.0), rtol=1e-12, atol=1e-300)
    with_nan = bonferroni_survival(np.array([np.nan, 1.0, 1e3]), 10, 3, np.array([5.0, 0.0, 5.0]))
    assert np.isnan(with_nan[0]) and np.isnan(with_nan[1]) and 0 < with_nan[2] < 1e-3


def test_chi2_tail_with_millions_of_degrees_of_freedom_against_scipy():
    stats = pytest.importorskip("scipy.stats")
    for k in (2_999_994, 600_000):
        for x in (k - 5000.0, k - 10.0, float(k), k + 2000.0, k + 12_000.0):
            assert chi2_survival(x, k) == pytest.approx(stats.chi2.sf(x, k), rel=1e-9, abs=1e-300), (x, k)


@pytest.mark.parametrize("k", [1, 2, 3, 6, 30])
def test_chi_median_against_mpmath(k):
    """The median of chi_k (the robust scale's denominator) needs no mpmath at run time."""
    from handeye.model.common.statistics import chi_median

    def below_half(x):
        return mpmath.gammainc(k / 2.0, 0, x / 2.0, regularized=True) - 0.5

    ref = float(mpmath.sqrt(mpmath.findroot(below_half, k - 2.0 / 3.0)))
    assert chi_median(k) == pytest.approx(ref, rel=1e-14)


@pytest.mark.parametrize("d1,d2,p", [(1, 5, 0.01), (3, 40, 1e-4), (6, 300, 0.3), (3, 69, 0.0025), (1, 10_000, 1e-6)])
def test_threshold_finds_the_quantile_in_few_evaluations(d1, d2, p):
    """:func:`threshold` (false position, Illinois, a bisection safeguard) ends at mpmath's quantile to its
    relative tolerance, on the side where the tail is still above ``p``, in at most half the ~45 evaluations
    bisection takes to 1e-12; a tail never as low as ``p`` gives inf, one below it at the start the start."""
    from handeye.model.common.statistics import threshold

    calls = []

    def tail(x):
        calls.append(x)
        return f_survival(x, d1, d2)

    x = threshold(tail, p)
    assert f_survival(x, d1, d2) > p
    z = mpmath.findroot(lambda t: _f_reference(float(t), d1, d2) - p, x)
    assert x == pytest.approx(float(z), rel=1e-10)
    assert len(calls) <= 24, len(calls)
    assert threshold(lambda t: 0.5, 0.1) == math.inf
    assert threshold(lambda t: 0.05, 0.1, lo=2.0, hi=3.0) == 2.0
