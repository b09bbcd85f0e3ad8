"""Robot motions for simulations: the thesis's strategy, rotations about the sphere, pure
translations.

Every function returns ``(ids, flange2base)`` with ``flange2base`` of shape (N, 4, 4) in mm:
the flange poses that put the sensor (true pose ``setup.sensor_pose`` on the flange) where it
sees the sphere (``setup.sphere_centre``) at the requested sensor-frame point. They feed
:func:`handeye.model.simulation.simulate.simulate` (``flange_poses``) and ``handeye simulate --motions``.

* ``thesis``: the seed's 36 orientations, the sphere seen at a random point of the working
  range (x in +-10 mm, |y| 3-20 mm on the setup's side, z 210-270 mm);
* ``about-sphere``: the same orientations with the sphere always at one sensor point: pure
  rotations about the sphere (Li et al.'s second step; a singular case for Kim & Cho's linear
  method, which needs the measured points to span 3-D);
* ``translations(k)``: at two of the orientations, ``k`` pure translations of the flange
  each (Li et al.'s first step). Added to either strategy.
"""
from __future__ import annotations

import numpy as np

from handeye.model.simulation.simulate import SimulationError, flanges_for_views, random_view, thesis_orientations

STRATEGIES = ("thesis", "about-sphere")

#: Sensor-frame displacements (mm) of the first pure translations: non-parallel, and the
#: sphere stays in the laser plane and the range.
TRANSLATION_STEPS = np.array([[15.0, 0.0, 0.0], [0.0, 0.0, 20.0], [0.0, 5.0, 0.0], [-10.0, 0.0, -15.0],
                              [8.0, -4.0, 10.0], [-12.0, 3.0, 12.0]])


def strategy(setup, rng, name="thesis", n_poses=36, translations=0):
    """Flange poses of a strategy (module docstring).

    Parameters
    ----------
    setup : handeye.model.simulation.simulate.Setup
    rng : numpy.random.Generator
    name : {'thesis', 'about-sphere'}
    n_poses : int
        Orientations of the thesis strategy (1..36).
    translations : int
        Pure translations added at each of two orientations (0 for none; at most 6 each).

    Returns
    -------
    ids : list of str
    flange2base : ndarray, shape (N, 4, 4)
    """
    if name not in STRATEGIES:
        raise SimulationError(f"unknown motion strategy {name!r}; choose one of {', '.join(STRATEGIES)}")
    if not 0 <= translations <= len(TRANSLATION_STEPS):
        raise SimulationError(f"translations must lie in 0..{len(TRANSLATION_STEPS)}, got {translations}")
    fixed = np.array([0.0, setup.side * 10.0, 240.0])
    ids, flanges, orientations = [], [], thesis_orientations(n_poses, setup.max_tilt_deg)
    for ident, rot in orientations:
        seen_at = fixed if name == "about-sphere" else random_view(setup, rng)
        ids.append(ident)
        flanges.append(flanges_for_views(setup, rot, seen_at))
    if translations:
        picks = sorted({0, len(orientations) // 2})
        for k in picks:
            ident, rot = orientations[k]
            for m, step in enumerate(TRANSLATION_STEPS[:translations]):
                seen_at = fixed - step * np.array([1.0, -setup.side, 1.0])  # the sensor moves by step
                ids.append(f"{ident}/t{m + 1}")
                flanges.append(flanges_for_views(setup, rot, seen_at))
            ids.append(f"{ident}/t0")
            flanges.append(flanges_for_views(setup, rot, fixed))
    return ids, np.array(flanges)
