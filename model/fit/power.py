"""What the data could not see: the score test's power, the effects it would miss, and the
Student-t scale of an interval whose noise is estimated from the fit.

**The score test's local power.** At a least-squares fit with Jacobian ``J`` (m, p) and noise
``sigma^2`` per residual, a candidate effect with Jacobian columns ``A`` (m, k) and true size
``theta`` leaves the residual ``r = (I - P) A theta + noise`` (``P`` the projection on the span of
``J``: the fitted parameters absorb the rest). The score statistic
``S = r^T a (a^T a)^-1 a^T r / sigma^2`` (``a = (I - P) A``, :func:`handeye.model.fit.score_tests.score_test`)
is then noncentral chi-square on k dof with noncentrality

    ``lambda = theta^T M theta``,  ``M = a^T a / sigma^2``

(the effect's information after projecting out the fitted parameters; Cox & Hinkley 1974,
*Theoretical Statistics*, sections 9.3 and 9.4: the score test's local power; the same as the Wald and
likelihood-ratio tests' to first order). At the search's level (``alpha`` over the ``n_tests``
candidates of its round, Bonferroni) the test rejects above ``c = chi2_k^-1(1 - alpha / n_tests)``;
it detects with probability :data:`POWER` when ``lambda >= lambda_P``, the root of
``P(chi2_k(lambda) > c) = POWER`` (:func:`detectable_noncentrality`; the noncentral tail is the
Poisson mixture ``sum_j e^-l/2 (l/2)^j / j! P(chi2_(k+2j) > c)``, Johnson, Kotz & Balakrishnan 1995,
*Continuous Univariate Distributions* 2, ch. 29). So the effects the test misses more often than
``1 - POWER`` form the ellipsoid ``theta^T M theta < lambda_P``: along its least-seen direction the
effect may be ``sqrt(lambda_P / mu_min(M))`` (effect units) and go unseen. With the noise estimated
from the fit on ``dof`` residual degrees of freedom (as the search estimates it) the statistic is a
noncentral F's, less powerful (:func:`detectable_noncentrality`); where it cannot reject at all
(its critical value beyond ``dof``: a 3-column effect at 12 dof, six poses with the sensor alone),
the size stated is the known-noise test's -- a lower bound of what such data can miss.

**What a missed effect does to the pose.** Left out of the model, ``theta`` moves the fitted
parameters by ``B theta``, ``B = (J^T J)^-1 J^T A`` (the alias matrix; omitted-variable bias). Over
the ellipsoid of missed effects the shifts fill ``{B theta}``, whose support in a direction ``u`` is
``sqrt(lambda_P u^T B M^-1 B^T u)``: the largest translation (mm) and rotation (deg) of the pose a
missed effect can cause are the square roots of the largest eigenvalues of ``lambda_P B M^-1 B^T`` on
those blocks (:func:`missable`). In the pose's own sd the largest shift is
``sqrt(lambda_P) |PA theta| / |(I - P) A theta|``: a geometric ratio that more poses of the same
geometry do not shrink -- but in mm and degrees it falls as ``1 / sqrt(n)``.

**The widened uncertainty.** The covariance ``lambda_P B M^-1 B^T / WIDEN_SD^2`` has that ellipsoid as
its :data:`WIDEN_SD`-sd region: added to the fit's covariance, every shift a missed effect can cause
lies within ``WIDEN_SD`` of the added sd in every direction. Only the part beyond :data:`SHIFT_FLOOR`
(mm, deg) is added (the covariance scaled by ``(1 - 1/q)^2``, ``q`` the largest shift over the floor,
:attr:`Missable.widening`): below the floor a shift is within what the calibration's promise
tolerates anyway (a pose is wrong only beyond 3 sd *and* beyond 0.2 mm / 0.05 deg, issue 39), so
where the power is high (many poses, low noise) the widening vanishes, and it grows from zero,
without a step, as the power falls. A gross error is such an effect too: its columns are one
sample's indicator, its information ``(I - H_ii) / sigma^2`` (``H_ii`` the sample's hat block), its
alias ``(J^T J)^-1 J_i^T`` (the sample's influence), tested at the outlier test's level over the
samples (:func:`missable_sample`: the sample where it moves the pose most).

**Student-t scale.** The fit's covariance is ``s^2 (J^T J)^-1`` with ``s^2 = SSR / (m - p)`` estimated
from the fit: a component's error over its sd is then Student-t on ``m - p`` dof, not normal. The
reported sd is scaled by :func:`t_factor` ``= t_dof^-1(Phi(3)) / 3`` so that ``+-3`` reported sd is
the exact t interval of the normal 3-sd coverage (99.73 %): 1.25 at 12 dof (6 poses, sensor only),
1.03 at 102 (36 poses). Units: ``J`` and ``B`` in the fit's step units (mm, rad, effect units).
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from handeye.model.common.statistics import chi2_survival, chi2_survival_array, f_survival, f_survival_array, threshold

#: The power at which a size is called detectable (80 %: the convention of power analysis, Cohen
#: 1988; an effect of that size is missed one time in five).
POWER = 0.8
#: The interval the promise is about: +-3 sd (its normal coverage 99.73 % is kept at low dof by
#: :func:`t_factor`; the widening puts every missed shift within this many sd).
WIDEN_SD = 3.0
#: Shifts of the pose below both (mm, deg) are within the promise's floor (issue 39: a pose is wrong
#: only beyond 3 sd and beyond 0.2 mm or 0.05 deg): no widening for them.
SHIFT_FLOOR = (0.2, 0.05)
#: Relative precision of the detectable noncentrality (a power of 0.8 to ~1e-5: far below what a
#: Monte Carlo of the power can see).
_RTOL = 1e-4
#: The Poisson mixture of the noncentral tail is summed to this many sd of its Poisson weights beyond
#: their mean ``lambda / 2`` (the weights beyond are below 1e-30), and at least 30 terms.
_MIXTURE_SD = 12.0


def _normal_cdf(z):
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


@functools.lru_cache(maxsize=1024)
def t_factor(dof, sd=WIDEN_SD):
    """``t_dof^-1(Phi(sd)) / sd``: the factor by which a sd from a fit with ``dof`` residual degrees of
    freedom is scaled so that +-``sd`` of it covers as +-``sd`` normal sd do (module docstring); 1 for
    no or infinite dof (a noise not estimated)."""
    if dof is None or not math.isfinite(dof) or dof <= 0:
        return 1.0
    tail = 2.0 * (1.0 - _normal_cdf(sd))  # two-sided: P(|T| > t) = P(F(1, dof) > t^2)
    t2 = threshold(lambda x: f_survival(x, 1, dof), tail)
    return float(math.sqrt(t2) / sd)


def _terms(lam):
    """How many terms of the Poisson mixture at noncentrality ``lam`` are summed (:data:`_MIXTURE_SD`)."""
    return int(lam / 2.0 + _MIXTURE_SD * math.sqrt(lam / 2.0)) + 30


class _Mixture:
    """``sum_j e^-l/2 (l/2)^j / j! T_j`` for any noncentrality ``l``: the central tails ``T_j`` (``tails(j)``,
    j an array) do not depend on ``l``, only the Poisson weights do, so a root search over ``l`` evaluates
    them once (extended as ``l`` grows), not once per trial."""

    def __init__(self, tails):
        self.tails = tails
        self.values = np.empty(0)
        self.log_factorial = np.empty(0)

    def __call__(self, lam):
        n = _terms(lam)
        if n > len(self.values):
            j = np.arange(max(n, 2 * len(self.values)))
            self.values = np.asarray(self.tails(j), float)
            self.log_factorial = np.concatenate([[0.0], np.cumsum(np.log(np.arange(1.0, len(j))))])
        j = np.arange(n)
        log_w = -lam / 2.0 + j * math.log(max(lam, 1e-300) / 2.0) - self.log_factorial[:n]
        return float(np.sum(np.exp(log_w) * self.values[:n]))


def _chi2_mixture(x, k):
    """P(chi2_k(l) > x) for any l: the mixture of the tails P(chi2_(k+2j) > x)."""
    return _Mixture(lambda j: chi2_survival_array(x, k + 2.0 * j))


def _f_mixture(x, k, d2):
    """P(F'(k, d2; l) > x) for any l: the mixture of the tails of ``F(k + 2j, d2)`` at ``x k / (k + 2j)``."""
    return _Mixture(lambda j: f_survival_array(x * k / (k + 2.0 * j), k + 2.0 * j, d2))


def noncentral_survival(x, k, lam):
    """P(chi2_k(lam) > x): the Poisson mixture of central tails (module docstring)."""
    if lam <= 0:
        return chi2_survival(x, k)
    return _chi2_mixture(x, k)(lam)


def noncentral_f_survival(x, k, d2, lam):
    """P(F'(k, d2; lam) > x): the Poisson mixture of central F tails, ``F(k + 2j, d2)`` at ``x k / (k + 2j)``."""
    return _f_mixture(x, k, d2)(lam)


@functools.lru_cache(maxsize=256)
def detectable_noncentrality(k, level, dof=None, power=POWER):
    """``lambda_P``: the noncentrality at which the score test of k columns at ``level`` rejects with
    ``power``; ``inf`` where it never does.

    With the noise known (``dof`` None) the statistic is chi2_k(lambda). With the noise estimated from
    the fit on ``dof = m - p`` residual dof, ``S = dof Q1 / (Q1 + Q2)`` (``Q1 ~ chi2_k(lambda)`` the part
    of the residual along the effect's columns, ``Q2 ~ chi2_(dof - k)`` the rest): S exceeds the
    chi-square critical value ``c`` exactly when ``(Q1 / k) / (Q2 / (dof - k)) > c (dof - k) / (k (dof - c))``,
    a noncentral F(k, dof - k) (its power lower than the chi-square's: the effect inflates the estimated noise).
    The root in ``lambda`` is found on one :class:`_Mixture` (its central tails evaluated once)."""
    crit = threshold(lambda x: chi2_survival(x, k), level)
    if dof is None:
        tail = _chi2_mixture(crit, k)
    elif dof <= k or crit >= dof:
        return math.inf
    else:
        tail = _f_mixture(crit * (dof - k) / (k * (dof - crit)), k, dof - k)
    return threshold(lambda lam: 1.0 - tail(lam), 1.0 - power, rtol=_RTOL)


@dataclasses.dataclass(frozen=True)
class Setting:
    """The test whose power is stated, as the search runs it.

    Attributes
    ----------
    sigma2 : float
        Noise variance per residual component (mm^2), as the test uses it.
    level : float
        The test's level (the search's alpha over its candidates; the outlier test's over the samples).
    dof : int or None
        Residual dof of ``sigma2`` when it is estimated from the fit (:func:`detectable_noncentrality`);
        None for a known noise.
    """

    sigma2: float
    level: float
    dof: int | None = None

    def noncentrality(self, k):
        """``lambda_P`` of a k-column test in this setting; the known-noise one where the estimated-noise
        test cannot reject at all (module docstring)."""
        lam = detectable_noncentrality(k, self.level, self.dof)
        return lam if math.isfinite(lam) else detectable_noncentrality(k, self.level)


@dataclasses.dataclass(frozen=True)
class Missable:
    """An effect the score test could have missed, and what it would do to the fit.

    Attributes
    ----------
    name : str
        Catalogue name.
    size : float
        Its detectable size (80 % power) along its least-seen direction, effect units (``unit``).
    unit : str
        ``mm``, ``deg``, ``deg/m``, or ``""`` (dimensionless: a scale, 0.001 = 0.1 %).
    shift_mm : float
        Largest translation of the pose a missed effect can cause, mm.
    shift_deg : float
        Largest rotation of the pose, degrees.
    shift_sd : float
        Largest shift in the pose's own sd (Mahalanobis, 6 dof, the fit's covariance).
    covariance : ndarray, shape (p, p)
        ``lambda_P B M^-1 B^T / WIDEN_SD^2`` in the fit's step units (its names).
    sample : str or None
        The sample of a gross error (``outlier``, :func:`missable_sample`), else None.
    """

    name: str
    size: float
    unit: str
    shift_mm: float
    shift_deg: float
    shift_sd: float
    covariance: np.ndarray
    sample: str | None = None

    @property
    def over_floor(self):
        """Its largest shift over :data:`SHIFT_FLOOR`: ``max(shift_mm / 0.2 mm, shift_deg / 0.05 deg)``."""
        return max(self.shift_mm / SHIFT_FLOOR[0], self.shift_deg / SHIFT_FLOOR[1])

    @property
    def beyond_floor(self):
        """Whether its shift passes :data:`SHIFT_FLOOR` (then it widens the uncertainty)."""
        return self.over_floor > 1.0

    @property
    def widening(self):
        """The covariance it adds to the fit's (the fit's step units): :attr:`covariance` scaled by
        ``(1 - 1 / over_floor)^2``, zero up to the floor -- the shift's part beyond the floor lies within
        :data:`WIDEN_SD` of the added sd, and the widening grows from zero as the power falls."""
        return self.covariance * max(1.0 - 1.0 / self.over_floor, 0.0) ** 2

    def text(self):
        """One phrase: the size and the shift."""
        size = f"{100 * self.size:.2g} %" if self.unit == "" else f"{self.size:.2g} {self.unit}"
        what = self.name if self.sample is None else f"a gross error of sample {self.sample}"
        return f"{what} up to {size} (moving the pose up to {self.shift_mm:.2g} mm / {self.shift_deg:.2g} deg)"


def missable(name, unit, jac, cols, setting):
    """The :class:`Missable` of a candidate effect at a fit (module docstring).

    Parameters
    ----------
    name, unit : str
    jac : ndarray, shape (m, p)
        The fit's Jacobian on the samples used; its first six columns ``tx, ty, tz`` (mm) and
        ``wx, wy, wz`` (rad) of the pose.
    cols : ndarray, shape (m, k)
        The effect's Jacobian columns at the fit.
    setting : Setting
        The score test's noise, its dof and level.

    Returns
    -------
    Missable or None
        None where the effect is not separable from the fit's parameters (no information after
        projecting them out) or the noise is zero.
    """
    sigma2 = setting.sigma2
    alias = np.linalg.lstsq(jac, cols, rcond=None)[0]  # B (p, k)
    perp = cols - jac @ alias
    m_eff = perp.T @ perp / sigma2 if sigma2 > 0 else np.zeros((cols.shape[1],) * 2)
    return missable_seen(name, unit, alias, m_eff, sigma2 * np.linalg.pinv(jac.T @ jac),
                         setting.noncentrality(cols.shape[1]))


def missable_seen(name, unit, alias, m_eff, cov, lam):
    """The :class:`Missable` of an effect whose information ``m_eff`` (k, k; per squared effect unit) may come
    from data other than the fit's residuals (a profile's shape: :mod:`handeye.app.engine.bend`), its alias
    ``alias`` (p, k: the fit's shift per effect unit), the fit's covariance ``cov`` (p, p) and the test's
    ``lam`` (:meth:`Setting.noncentrality`); None where the effect is not seen at all."""
    eig = np.linalg.eigvalsh(m_eff)
    if not np.all(np.isfinite(m_eff)) or eig[0] <= 1e-12 * max(eig[-1], 1e-300):
        return None
    shifts = lam * alias @ np.linalg.solve(m_eff, alias.T)  # the ellipsoid of shifts, as a (p, p) form
    pose = slice(0, 6)
    sd = math.sqrt(max(float(np.max(np.linalg.eigvals(np.linalg.pinv(cov[pose, pose]) @ shifts[pose, pose]).real)), 0.0))
    return Missable(name, float(math.sqrt(lam / eig[0])), unit,
                    float(math.sqrt(max(np.linalg.eigvalsh(shifts[:3, :3])[-1], 0.0))),
                    float(np.degrees(math.sqrt(max(np.linalg.eigvalsh(shifts[3:6, 3:6])[-1], 0.0)))),
                    sd, shifts / WIDEN_SD**2)


def missable_sample(jac, setting, ids):
    """The gross error the deletion test could miss on the sample where it moves the pose most: a
    :class:`Missable` named ``outlier`` (module docstring, the effect's columns the sample's
    indicator: ``M_i = (I - H_ii) / sigma^2``, ``B_i = (J^T J)^-1 J_i^T``), or None.

    Parameters
    ----------
    jac : ndarray, shape (n, 3, p)
        The fit's Jacobian of each used sample (pose first: mm, rad).
    setting : Setting
        The noise, its dof, and the deletion test's level per sample (the family-wise level over the
        samples, Bonferroni).
    ids : sequence of str
        The samples' ids.

    Returns
    -------
    Missable or None
        None where no sample's gross error is separable from the fit (every sample of leverage 1).
    """
    sigma2, flat = setting.sigma2, jac.reshape(-1, jac.shape[2])
    inv = np.linalg.pinv(flat.T @ flat)
    alias = np.einsum("pq,niq->npi", inv, jac)  # B_i (n, p, 3)
    m_eff = (np.eye(3) - np.einsum("nip,npj->nij", jac, alias)) / sigma2
    eig = np.linalg.eigvalsh(m_eff)
    seen = eig[:, 0] > 1e-9 * max(float(np.max(eig)), 1e-300)
    if not np.any(seen) or sigma2 <= 0:
        return None
    lam = setting.noncentrality(3)
    alias, m_eff, eig = alias[seen], m_eff[seen], eig[seen]
    shifts = lam * alias @ np.linalg.solve(m_eff, np.swapaxes(alias, 1, 2))
    shift_mm = np.sqrt(np.clip(np.linalg.eigvalsh(shifts[:, :3, :3])[:, -1], 0.0, None))
    shift_deg = np.degrees(np.sqrt(np.clip(np.linalg.eigvalsh(shifts[:, 3:6, 3:6])[:, -1], 0.0, None)))
    k = int(np.argmax(np.maximum(shift_mm / SHIFT_FLOOR[0], shift_deg / SHIFT_FLOOR[1])))
    cov = sigma2 * inv[:6, :6]
    sd = math.sqrt(max(float(np.max(np.linalg.eigvals(np.linalg.pinv(cov) @ shifts[k, :6, :6]).real)), 0.0))
    return Missable("outlier", float(math.sqrt(lam / eig[k, 0])), "mm", float(shift_mm[k]), float(shift_deg[k]), sd,
                    shifts[k] / WIDEN_SD**2, str(np.asarray(ids)[seen][k]))
