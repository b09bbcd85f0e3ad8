"""The sphere fitted to a 3-D sensor's point cloud (model/geometry/sphere_cloud.py): the fit against scipy's
least squares, its centre covariance against Monte Carlo, the cleaning, and clouds that are no sphere named."""
import numpy as np
import pytest
from scipy.optimize import least_squares

from handeye.model.geometry import sphere_cloud

CENTRE = np.array([4.0, -3.0, 300.0])
RADIUS = 25.4


def cap(rng, n=800, half_deg=55.0, noise=0.03, centre=CENTRE, radius=RADIUS):
    """Points on the cap of the sphere that faces the sensor at the origin (-z from the centre), with noise."""
    axis = -centre / np.linalg.norm(centre)
    u = rng.uniform(np.cos(np.radians(half_deg)), 1.0, n)  # uniform over the cap's area
    phi = rng.uniform(0, 2 * np.pi, n)
    e1 = np.cross(axis, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    s = np.sqrt(1 - u**2)
    d = u[:, None] * axis + (s * np.cos(phi))[:, None] * e1 + (s * np.sin(phi))[:, None] * e2
    return centre + radius * d + noise * rng.normal(size=d.shape)


def scipy_sphere(points, radius=None):
    """The geometric least-squares sphere by scipy (an independent fit): centre, radius."""
    def res(p):
        r = p[3] if radius is None else radius
        return np.linalg.norm(points - p[:3], axis=1) - r
    start = np.r_[points.mean(axis=0) + [0, 0, 10], 20.0]
    sol = least_squares(res, start, xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return sol.x[:3], (sol.x[3] if radius is None else radius)


@pytest.mark.parametrize("radius", [RADIUS, None], ids=["radius held", "radius free"])
def test_the_fit_is_scipys_least_squares_sphere(radius):
    pts = cap(np.random.default_rng(1))
    fit = sphere_cloud.fit_cloud(pts, radius)
    centre, r = scipy_sphere(pts, radius)
    assert np.allclose(fit.centre, centre, atol=1e-7)
    assert fit.radius == pytest.approx(r, abs=1e-7)
    assert fit.radius_held == (radius is not None) and fit.n_dropped == 0
    assert np.linalg.norm(fit.centre - CENTRE) < 0.05


@pytest.mark.parametrize("radius", [RADIUS, None], ids=["radius held", "radius free"])
def test_the_centre_covariance_is_the_monte_carlo_one(radius):
    """200 seeded draws of the same cap: the sd of the fitted centres against the fit's own, each axis within 20 %."""
    rng = np.random.default_rng(7)
    base = cap(rng, n=400, noise=0.0)
    fits = [sphere_cloud.fit_cloud(base + 0.05 * rng.normal(size=base.shape), radius) for _ in range(200)]
    observed = np.std([f.centre for f in fits], axis=0, ddof=1)
    predicted = np.sqrt(np.mean([np.diag(f.covariance) for f in fits], axis=0))
    assert np.all(np.abs(observed / predicted - 1) < 0.2), (observed, predicted)
    if radius is None:  # the radius's sd too
        assert np.std([f.radius for f in fits], ddof=1) == pytest.approx(np.mean([f.radius_sd for f in fits]), rel=0.2)


def test_outliers_are_cleaned_off_and_counted():
    rng = np.random.default_rng(3)
    pts = cap(rng)
    junk = CENTRE + rng.uniform(-40, 40, size=(40, 3))
    junk = junk[np.abs(np.linalg.norm(junk - CENTRE, axis=1) - RADIUS) > 1.0]  # off the sphere by a millimetre or more
    fit = sphere_cloud.fit_cloud(np.vstack([pts, junk]), RADIUS)
    assert fit.n_dropped == len(junk) and not fit.kept[len(pts):].any() and fit.kept[:len(pts)].all()
    clean = sphere_cloud.fit_cloud(pts, RADIUS)
    assert np.allclose(fit.centre, clean.centre, atol=1e-9)
    assert fit.describe() == f"{len(junk)} of {len(pts) + len(junk):,} points dropped: off the sphere {len(junk)}"


@pytest.mark.parametrize("radius", [RADIUS, None], ids=["radius held", "radius free"])
@pytest.mark.parametrize("case, words", [
    ("plane", "plane"),
    ("few", "at least 20"),
    ("small cap", "plane, or a cap too flat"),
    ("scatter", "no sphere"),
])
def test_a_cloud_that_is_no_sphere_is_refused_with_why(case, words, radius):
    rng = np.random.default_rng(5)
    clouds = {"plane": np.column_stack([rng.uniform(-20, 20, (500, 2)), 300 + 0.03 * rng.normal(size=500)]),
              "few": cap(rng, n=12), "small cap": cap(rng, n=500, half_deg=5.0),
              "scatter": CENTRE + rng.uniform(-30, 30, (500, 3))}
    with pytest.raises(sphere_cloud.CloudError, match=words):
        sphere_cloud.fit_cloud(clouds[case], radius)


def test_a_wrong_stated_diameter_is_named_with_the_clouds_own():
    with pytest.raises(sphere_cloud.CloudError, match=r"diameter is 50\.8.* not the stated 52 mm"):
        sphere_cloud.fit_cloud(cap(np.random.default_rng(2)), 26.0)
