"""Tail probabilities (vectorised continued fractions) against mpmath, at the tails and for the
degrees of freedom of large datasets; they terminate on NaN and infinity."""
import math

import mpmath
import numpy as np
import pytest

from handeye.model.statistics import chi2_survival, chi2_survival_array, f_survival, f_survival_array


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


@pytest.mark.parametrize("k", [1, 2, 3, 6, 30])
def test_chi_median_against_mpmath(k):
    """The median of chi_k (the robust scale's denominator) needs no mpmath at run time."""
    from handeye.model.statistics import chi_median

    def below_half(x):
        return mpmath.gammainc(k / 2.0, 0, x / 2.0, regularized=True) - 0.5

    ref = float(mpmath.sqrt(mpmath.findroot(below_half, k - 2.0 / 3.0)))
    assert chi_median(k) == pytest.approx(ref, rel=1e-14)
