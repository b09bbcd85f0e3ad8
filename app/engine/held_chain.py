"""The extended chain held at a pose: what a saved calibration, a power statement or a correction's
uncertainty is evaluated with (never fitted here).

One construction (an engine module: the datasets' metric and the fit's problem together), used by
:func:`handeye.app.engine.diagnose.held_power`,
:func:`handeye.app.engine.held_effects.recompute` and :mod:`handeye.app.engine.bend`: the samples'
own centre metric at the pose (:func:`handeye.model.datasets.observations.centre_metric`), the
:class:`~handeye.model.fit.extended.Samples` problem in it, the structure (the sphere centre free or
held, the data effects) and the point ``x`` of the pose and centre.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.datasets import observations
from handeye.model.fit.extended import Samples, Structure


@dataclasses.dataclass(frozen=True)
class Held:
    """The chain held at a pose.

    Attributes
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
        With the held sphere centre.
    prob : handeye.model.fit.extended.Samples
    structure : handeye.model.fit.extended.Structure
    x : ndarray
        The point of the pose (local chart) and the centre.
    """

    dataset: object
    prob: object
    structure: object
    x: np.ndarray

    def with_centres(self, centre_in_sensor):
        """The same held chain on other measured centres (N, 3; sensor frame, mm), in the same metric."""
        data = dataclasses.replace(self.dataset, centre_in_sensor=np.asarray(centre_in_sensor, float))
        prob = Samples(data, self.prob.sigma, self.prob.metric)
        prob.robot_free.update(self.prob.robot_free)
        return dataclasses.replace(self, dataset=data, prob=prob)


def held_at(dataset, mask, at, centre_free, effect_names=(), stated=None):
    """The :class:`Held` chain of ``dataset`` at ``at`` = ``(sensor2flange, centre)``: the pose (4x4, mm) and
    the sphere centre (its mount's frame, mm; None: the dataset's), the metric of the samples in ``mask``;
    ``centre_free``: the centre among the parameters; ``effect_names``: data effects in the structure;
    ``stated``: the stated centre noise (mm) the problem scales with."""
    sensor2flange, centre = at
    pose = np.asarray(sensor2flange, float)
    centre = np.asarray(centre if centre is not None else dataset.sphere_centre, float)
    held = dataclasses.replace(dataset, sphere_centre=centre)  # a free centre's start: the one given
    metric = observations.centre_metric(held, pose, centre, mask, 9 if centre_free else 6)
    prob = Samples(held, stated, metric)
    structure = Structure(centre=bool(centre_free), data_effects=tuple(effect_names))
    return Held(held, prob, structure, prob.point(structure, pose, centre))
