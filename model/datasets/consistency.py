"""Every row consistent with itself: a row's centre columns against its own profile.

A row of ``measurements.csv`` may give both the sphere centre the sensor reported,
``(xs, ys, zs)`` (mm, sensor frame), and the laser profile it was computed from (points
``(x, z)`` in the sensor's y = 0 plane, mm). The two describe one measurement, so they must
agree: the laser plane cuts a sphere of radius R centred at ``(xs, ys, zs)`` in the circle

    centre ``(xs, zs)``, radius ``sqrt(R^2 - ys^2)``        (in the sensor's x-z plane, mm)

and the profile's fitted circle ``(xc, zc, r)`` must be that circle. A profile that is the
neighbour's (a copy-paste slip in the ``profile`` column), a centre typed into the wrong row,
or a centre from another scan breaks this, and no fit of the robot chain can tell: the centre
residual sees a good centre, the profile residuals a good circle, and a model that uses both
(screening on the centres, the final fit on the profiles) smears the contradiction over every
row.

Why compare circles, not centres: near the sphere's equator (r close to R) the profile
determines ``|y| = sqrt(R^2 - r^2)`` badly (``dy = -(r/|y|) dr``), so a centre reconstructed
from the profile would carry a huge, one-sided error. In the circle's coordinates the
comparison stays linear and well conditioned: the predicted radius moves with ys by
``dr = -(ys / r) dys``, which vanishes at the equator.

The test, per row with both (its uncertainty as stated, never estimated from the rows):

* the difference ``d = (xc, zc, r) - (xs, zs, sqrt(R^2 - ys^2))`` (mm);
* its covariance ``S = C_fit + J diag(s^2) J^T``: ``C_fit`` the circle fit's
  (:func:`handeye.model.geometry.circle.circle_covariance`, from the profile's own scatter about the
  circle), ``s`` the stated per-component sd of a centre (``[noise] centre_mm``) and
  ``J = d(xs, zs, r_pred)/d(xs, ys, zs)``; where ``R^2 - ys^2`` is near or below zero the
  slope ``ys / r_pred`` uses ``r_pred >= sqrt(2 R s)`` (the radius a one-sd move of ys gives
  at the plane's tangent), so that the linearisation cannot hide a row whose plane misses
  the sphere;
* ``D^2 = d^T S^-1 d ~ chi^2_3`` when the row is consistent; Bonferroni over the rows
  checked, at the strict family-wise level :data:`ALPHA`;
* and a physical floor: a row is inconsistent only when also ``|d| >``
  :data:`MIN_DISAGREEMENT_MM`. A profile fitted to 1,000 points has a covariance of microns,
  so a real sensor's centre, computed by its own fit from its own filtered points, can differ
  from ours by many of its standard deviations while agreeing to far better than the sensor's
  accuracy; the floor keeps such rows in. A neighbour's profile differs by millimetres.

Nothing here decides what to do with an inconsistent row (:mod:`handeye.app.engine.robust` excludes
it in calibrate and diagnose alike).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.statistics import chi2_survival_array
from handeye.model.datasets import observations

#: Family-wise level of the per-row test (Bonferroni over the rows checked): strict, because a
#: flagged row is excluded.
ALPHA = 1e-3
#: A row is inconsistent only when its circle and its centre columns also differ by more than
#: this (mm, Euclidean norm of the (xc, zc, r) difference): a physical floor far above a
#: laser-line sensor's accuracy (tens of microns) and far below what a neighbour's profile
#: gives (millimetres).
MIN_DISAGREEMENT_MM = 0.5
#: The circle fit of the profile models (one definition, :mod:`handeye.model.datasets.observations`).
CIRCLE_FIT = observations.CIRCLE_FIT


@dataclasses.dataclass(frozen=True)
class RowCheck:
    """The comparison of one row's centre columns with its profile.

    Attributes
    ----------
    index : int
        Position of the row among the dataset's measurements (0-based).
    id : str
    row : int
        Line in ``measurements.csv``.
    fitted : ndarray, shape (3,)
        The profile's circle ``(xc, zc, r)``, sensor x-z plane, mm.
    predicted : ndarray, shape (3,)
        The circle the centre columns predict, ``(xs, zs, sqrt(R^2 - ys^2))`` (mm; radius 0
        where ``|ys| >= R``: the plane misses the sphere).
    difference_mm : ndarray, shape (3,)
        ``fitted - predicted``, mm.
    disagreement_mm : float
        ``|difference_mm|``, mm.
    sd : float
        Mahalanobis distance ``sqrt(D^2)`` of the difference under its stated covariance
        (how many standard deviations).
    p_bonferroni : float
        ``P(chi^2_3 > D^2)`` times the number of rows checked, at most 1.
    inconsistent : bool
        ``p_bonferroni < alpha`` and ``disagreement_mm > min_mm``.
    """

    index: int
    id: str
    row: int
    fitted: np.ndarray
    predicted: np.ndarray
    difference_mm: np.ndarray
    disagreement_mm: float
    sd: float
    p_bonferroni: float
    inconsistent: bool

    @property
    def reason(self):
        """One sentence naming the row and the evidence."""
        dx, dz, dr = self.difference_mm
        return (f"row {self.row} (sample {self.id!r}) contradicts itself: its profile's circle (x {self.fitted[0]:.3f}, "
                f"z {self.fitted[1]:.3f}, r {self.fitted[2]:.3f}) mm is not the cut its centre columns xs, ys, zs "
                f"predict (x {self.predicted[0]:.3f}, z {self.predicted[1]:.3f}, r {self.predicted[2]:.3f}) mm: "
                f"{self.disagreement_mm:.3g} mm apart (dx {dx:+.3f}, dz {dz:+.3f}, dr {dr:+.3f}), {self.sd:.3g} sd, "
                f"Bonferroni p {'= ' if self.p_bonferroni > 1e-300 else '< '}{max(self.p_bonferroni, 1e-300):.2g}; is "
                "the profile file another row's, or the centre another scan's?")


@dataclasses.dataclass(frozen=True)
class Consistency:
    """Outcome of :func:`check_rows`.

    Attributes
    ----------
    checked : tuple of RowCheck
        Every row that gives both centre columns and a profile, in dataset order.
    n : int
        Number of measurements in the dataset.
    alpha : float
    min_mm : float
    """

    checked: tuple
    n: int
    alpha: float = ALPHA
    min_mm: float = MIN_DISAGREEMENT_MM

    @property
    def inconsistent(self):
        """The rows that contradict themselves (list of RowCheck)."""
        return [c for c in self.checked if c.inconsistent]

    @property
    def consistent(self):
        """Mask (n,) of bool: False for the rows that contradict themselves."""
        mask = np.ones(self.n, bool)
        mask[[c.index for c in self.inconsistent]] = False
        return mask


def predicted_circle(centres, radius, sigma_centre):
    """The circles that sphere centres predict in the laser plane, and their covariances.

    Parameters
    ----------
    centres : array_like, shape (N, 3)
        Sphere centres ``(xs, ys, zs)`` in the sensor frame, mm.
    radius : float
        Sphere radius R, mm.
    sigma_centre : float
        Stated sd of each centre component, mm.

    Returns
    -------
    circles : ndarray, shape (N, 3)
        ``(xs, zs, sqrt(max(R^2 - ys^2, 0)))``, mm.
    covariances : ndarray, shape (N, 3, 3)
        ``J diag(s^2) J^T`` with the radius slope ``-ys / max(r_pred, sqrt(2 R s))`` (module
        docstring), mm^2.
    """
    centres = np.atleast_2d(np.asarray(centres, float))
    ys = centres[:, 1]
    r_pred = np.sqrt(np.clip(radius**2 - ys**2, 0.0, None))
    slope = -ys / np.maximum(r_pred, np.sqrt(2.0 * radius * sigma_centre))
    jac = np.zeros((len(centres), 3, 3))
    jac[:, 0, 0] = 1.0
    jac[:, 1, 2] = 1.0
    jac[:, 2, 1] = slope
    cov = sigma_centre**2 * np.einsum("nij,nkj->nik", jac, jac)
    return np.column_stack([centres[:, 0], centres[:, 2], r_pred]), cov


def compare(fitted, fitted_cov, centres, radius, sigma_centre):
    """Differences between fitted circles and the circles centres predict, and their size in sd.

    Parameters
    ----------
    fitted : array_like, shape (N, 3)
        Circles ``(xc, zc, r)`` fitted to the profiles, sensor x-z plane, mm.
    fitted_cov : array_like, shape (N, 3, 3)
        Their covariances, mm^2.
    centres : array_like, shape (N, 3)
        The same rows' centre columns ``(xs, ys, zs)``, sensor frame, mm.
    radius : float
        Sphere radius R, mm.
    sigma_centre : float
        Stated sd of each centre component, mm.

    Returns
    -------
    difference : ndarray, shape (N, 3)
        ``fitted - predicted``, mm.
    predicted : ndarray, shape (N, 3)
        The predicted circles, mm.
    d2 : ndarray, shape (N,)
        Squared Mahalanobis distances ``d^T (C_fit + C_pred)^-1 d``, ~ chi^2_3 when consistent.
    """
    fitted = np.atleast_2d(np.asarray(fitted, float))
    predicted, cov_pred = predicted_circle(centres, radius, sigma_centre)
    difference = fitted - predicted
    total = np.asarray(fitted_cov, float).reshape(-1, 3, 3) + cov_pred
    d2 = np.einsum("ni,ni->n", difference, np.linalg.solve(total, difference[..., None])[..., 0])
    return difference, predicted, d2


def check_rows(dataset, alpha=ALPHA, min_mm=MIN_DISAGREEMENT_MM, sigma_centre=None, fit=CIRCLE_FIT):
    """Check every row that gives both centre columns and a profile (module docstring).

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
        Rows whose centre was reconstructed from their profile (``reconstructed``) agree by
        construction and are not checked; nor are rows without a profile.
    alpha : float
        Family-wise level (Bonferroni over the rows checked).
    min_mm : float
        Physical floor of a disagreement, mm.
    sigma_centre : float, optional
        Stated sd of a centre component, mm; default the dataset's ``[noise] centre_mm``.
    fit : str
        Circle fit (:data:`handeye.model.geometry.circle.FITS`).

    Returns
    -------
    Consistency

    Raises
    ------
    InputError
        When a checked row's profile admits no circle (named with its row and column).
    """
    n = len(dataset)
    if dataset.profiles is None:
        return Consistency((), n, alpha, min_mm)
    rebuilt = dataset.reconstructed or (False,) * n
    both = [k for k in range(n) if dataset.profiles[k] is not None and not rebuilt[k]]
    if not both:
        return Consistency((), n, alpha, min_mm)
    sigma = dataset.noise_centre_mm if sigma_centre is None else float(sigma_centre)
    mask = np.zeros(n, bool)
    mask[both] = True
    fitted, covs = observations.circles(dataset.subset(mask), fit)  # names a row whose profile cannot be fitted
    difference, predicted, d2 = compare(fitted, covs, dataset.centre_in_sensor[both],
                                        dataset.sphere_diameter / 2, sigma)
    p_adj = np.minimum(chi2_survival_array(d2, 3) * len(both), 1.0)
    size = np.linalg.norm(difference, axis=1)
    checked = tuple(
        RowCheck(index=k, id=dataset.ids[k], row=int(dataset.rows[k]), fitted=fitted[j], predicted=predicted[j],
                 difference_mm=difference[j], disagreement_mm=float(size[j]), sd=float(np.sqrt(max(d2[j], 0.0))),
                 p_bonferroni=float(p_adj[j]), inconsistent=bool(p_adj[j] < alpha and size[j] > min_mm))
        for j, k in enumerate(both))
    return Consistency(checked, n, alpha, min_mm)
