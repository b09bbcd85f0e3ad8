"""An independent generator of profile-only cells, and of profiles that are no arc of the sphere
(numpy and the standard library only; no code of ``handeye``).

The poses, the sensor mount and the sphere come from :func:`indep_cells.make_cell` (its exact
centres in the sensor frame, ``true_points``, drawn as for centre-only cells: ``|ys|`` from 0.08 R
to 0.9 R, so that some cuts lie near the equator, where the centre's y is poorly determined); the
profiles are drawn here, another way than ``indep_cells`` draws them, from the physics of a
laser-line triangulation sensor:

* the laser plane is the sensor's y = 0; it cuts the sphere (radius R, centre ``p = (xs, ys, zs)``
  in the sensor frame after the robot's repeatability moved it by ``N(0, robot_sd^2)`` per
  component) in the circle of radius ``r = sqrt(R^2 - ys^2)`` about ``(xs, zs)``;
* the camera at the sensor origin sees the points of that circle whose outward normal makes an
  angle below ``max_incidence`` (70-85 deg) with the ray back to the origin: a contiguous arc;
* the points are drawn at uniformly random angles on that arc (``spacing`` mm on average) and each
  moves along its own viewing ray by ``N(0, point_sd^2)`` (a triangulation sensor's error is a
  range error), so the noise is neither isotropic nor normal to the circle.

A profile of something else than the stated sphere (:data:`BAD_KINDS`), laid where the arc would
be so that the rows look plausible:

* ``line`` -- a flat surface across the arc's chord, as far from the sensor as the arc's nearest
  point;
* ``corner`` -- an edge target: two flat faces meeting at the arc's nearest point at an opening
  of 100-140 deg;
* ``segments`` -- two flat pieces at depths 2-6 mm apart, a step between them;
* ``small`` -- an arc of a circle of radius 0.8 R about the arc's own centre (a cut of a smaller
  sphere, or a circle of another radius).

Public: :func:`make_arc_cell` (an ``indep_cells.Cell`` with these profiles, every row
profile-only), :func:`bad_profile`, :func:`write` (``indep_cells.write_dataset``).
"""
from __future__ import annotations

import dataclasses
import math

import indep_cells as ic
import numpy as np

BAD_KINDS = ("line", "corner", "segments", "small")


def _visible_arc(centre_xz, r, max_incidence_deg):
    """The angles (lo, hi) (rad, lo < hi) of the circle's points whose outward normal is within
    ``max_incidence_deg`` of the ray back to the sensor origin."""
    cx, cz = centre_xz
    facing = math.atan2(-cz, -cx)  # the normal that points at the origin
    lo, hi = facing - math.pi / 2, facing + math.pi / 2
    grid = np.linspace(lo, hi, 2001)
    px, pz = cx + r * np.cos(grid), cz + r * np.sin(grid)
    ray = -np.column_stack([px, pz]) / np.hypot(px, pz)[:, None]
    cos_inc = np.cos(grid) * ray[:, 0] + np.sin(grid) * ray[:, 1]
    seen = grid[cos_inc > math.cos(math.radians(max_incidence_deg))]
    return float(seen.min()), float(seen.max())


def _range_noise(rng, pts, point_sd):
    """Each point moved along its viewing ray from the origin by N(0, point_sd^2), mm."""
    ray = pts / np.linalg.norm(pts, axis=1)[:, None]
    return pts + ray * rng.normal(scale=point_sd, size=(len(pts), 1))


def arc_profile(rng, centre_xz, r, point_sd, spacing, max_incidence_deg):
    """The visible arc of the circle (centre (x, z), radius r, mm) as (K, 2) noisy points."""
    lo, hi = _visible_arc(centre_xz, r, max_incidence_deg)
    k = max(15, int((hi - lo) * r / spacing))
    phi = np.sort(rng.uniform(lo, hi, k))
    pts = np.column_stack([centre_xz[0] + r * np.cos(phi), centre_xz[1] + r * np.sin(phi)])
    return _range_noise(rng, pts, point_sd)


def _piece(a, b, spacing, rng):
    """Points drawn uniformly on the segment a-b (2,), ``spacing`` mm apart on average."""
    k = max(8, int(np.linalg.norm(b - a) / spacing))
    t = np.sort(rng.uniform(0, 1, k))[:, None]
    return a + t * (b - a)


def bad_profile(rng, kind, centre_xz, r, radius, point_sd, spacing):
    """A profile of something else than the sphere (module docstring), (K, 2), mm."""
    lo, hi = _visible_arc(centre_xz, r, 80.0)
    c = np.asarray(centre_xz, float)
    facing = math.atan2(-c[1], -c[0])
    near = c + r * np.array([math.cos(facing), math.sin(facing)])  # the arc's point nearest the sensor
    along = np.array([-math.sin(facing), math.cos(facing)])  # the tangent there
    half = r * math.sin((hi - lo) / 2)  # half the chord
    if kind == "line":
        pts = _piece(near - half * along, near + half * along, spacing, rng)
    elif kind == "corner":
        opening = math.radians(rng.uniform(100, 140))
        back = -np.array([math.cos(facing), math.sin(facing)])  # away from the sensor
        slope = math.tan((math.pi - opening) / 2)
        pts = np.vstack([_piece(near, near + half * (s * along + slope * back), spacing, rng) for s in (-1, 1)])
    elif kind == "segments":
        step = rng.uniform(2, 6) * rng.choice([-1, 1])
        back = -np.array([math.cos(facing), math.sin(facing)])
        pts = np.vstack([_piece(near - half * along, near - 0.1 * half * along, spacing, rng),
                         _piece(near + 0.1 * half * along + step * back, near + half * along + step * back, spacing, rng)])
    elif kind == "small":
        return arc_profile(rng, c, 0.8 * radius, point_sd, spacing, 80.0)
    else:
        raise ValueError(f"unknown bad profile {kind!r}; one of {BAD_KINDS}")
    return _range_noise(rng, pts, point_sd)


def make_arc_cell(seed, *, point_sd=None, robot_sd=None, bad=None, **options):
    """A profile-only cell (module docstring): ``indep_cells.make_cell(seed, profiles='none',
    **options)``'s poses with profiles drawn here.

    point_sd: range noise of a profile point, mm (drawn 0.005-0.05); robot_sd: the robot's
    repeatability, moving each row's sphere centre, mm per component (drawn 0-0.02); bad: dict
    row index -> a kind of :data:`BAD_KINDS` (those rows' profiles are no arc of the sphere).
    ``cell.notes`` gains ``point_sd``, ``robot_sd``, ``bad``; ``cell.measured`` holds the
    centres the profiles were drawn from.
    """
    cell = ic.make_cell(seed, profiles="none", sigma=1e-9, **options)  # 'none': cuts from near the pole to near the equator
    rng = np.random.default_rng(seed + 104729)
    point_sd = float(point_sd if point_sd is not None else rng.uniform(0.005, 0.05))
    robot_sd = float(robot_sd if robot_sd is not None else rng.uniform(0.0, 0.02))
    spacing = float(rng.uniform(0.05, 0.25))
    radius = cell.diameter / 2
    centres = cell.true_points + rng.normal(scale=robot_sd, size=cell.true_points.shape)
    bad = dict(bad or {})
    profiles = []
    for i, (xs, ys, zs) in enumerate(centres):
        r = math.sqrt(radius**2 - ys**2)
        if i in bad:
            profiles.append(bad_profile(rng, bad[i], (xs, zs), r, radius, point_sd, spacing))
        else:
            profiles.append(arc_profile(rng, (xs, zs), r, point_sd, spacing, rng.uniform(70, 85)))
    notes = dict(cell.notes, point_sd=point_sd, robot_sd=robot_sd, bad={int(k): v for k, v in bad.items()},
                 spacing=spacing)
    return dataclasses.replace(cell, measured=centres, profiles=profiles, modes=["profile"] * len(centres),
                               sigma=robot_sd, notes=notes, state_noise=False)


def write(cell, folder, **options):
    """``indep_cells.write_dataset`` of the cell (its folder)."""
    return ic.write_dataset(cell, folder, **options)
