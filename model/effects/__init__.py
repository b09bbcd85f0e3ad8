"""The effect catalogue: named extensions of the measurement model.

Every effect's parameters are zero when it is absent, so models nest. Three kinds:

* ``data`` -- the effect changes what the sensor reports; the module gives the symbolic
  *correction* ``xs_true = g(xs_measured; params)`` (sympy, from which the Jacobian with respect
  to the parameters is generated like the base model's). ``sensor_scale``, ``centre_scale``,
  ``sphere_radius``.
* ``centre`` -- ``sphere_center``: the true centre is the setup's plus (dx, dy, dz); estimated by
  making the centre an unknown.
* ``discrete`` -- ``sign_flip`` and ``outlier``: per-sample, decided by the final outlier test.
* ``robot`` -- ``joint_offsets``, ``link_lengths``, ``joint_compliance``: the robot did not reach
  the pose it reported; the flange pose of each sample is corrected through the robot's nominal
  kinematics (:mod:`handeye.model.robot.robot_errors`), with only the parameters the poses can separate
  from the sensor pose and the sphere centre; their names depend on the robot model
  (``params(model)``).
* ``structural`` -- effects the poses can never separate from the sensor pose and the sphere
  centre (a constant error of the robot base frame or of the flange frame, a laser-plane
  offset or tilt). They are in the catalogue to be *reported* as absorbed, never named.

The order of :data:`MODULES` is the physical prior: of two sets of effects the data cannot tell
apart (a line scanner's ``sensor_scale`` is, to first order, ``centre_scale`` plus a
``sphere_radius`` of R s), the search names the one whose effects come first.

Adding an effect is one small module with ``NAME``, ``KIND``, ``PARAMS``, ``DOC`` and, for
``data`` effects, ``correction(xm, ym, zm, R, params)`` returning the corrected centre
(sympy), or, for ``structural`` ones, ``columns(parts)`` returning its Jacobian columns.
"""
from __future__ import annotations

import functools
import importlib

import numpy as np

from handeye.model.chain import codegen

MODULES = ("sphere_center", "sensor_scale", "sphere_radius", "centre_scale", "sign_flip", "outlier",
           "base_frame", "flange_frame", "laser_plane", "joint_offsets", "link_lengths", "joint_compliance")


@functools.lru_cache(maxsize=None)
def get(name):
    """The effect module called ``name``."""
    if name not in MODULES:
        raise ValueError(f"unknown effect {name!r}; the catalogue has {', '.join(MODULES)}")
    return importlib.import_module(f"handeye.model.effects.{name}")


#: Physical limits of the data effects' parameters: beyond them a fitted value does not describe
#: the effect but absorbs something else (a wrong side, diameter or unit).
LIMITS = {
    "sensor_scale": ("a scale error of at most 5 %", lambda params, radius: abs(params[0]) <= 0.05),
    "centre_scale": ("a scale error of at most 5 %", lambda params, radius: abs(params[0]) <= 0.05),
    "sphere_radius": ("a radius error of at most 20 % of the radius", lambda params, radius: abs(params[0]) <= 0.2 * radius),
    # a robot's errors: mastering within a degree or two, lengths within millimetres, a sag of a
    # few tenths of a degree at a metre's lever (a controller's nominal model is that close)
    "joint_offsets": ("joint zero offsets of at most 2 deg", lambda params, radius: np.all(np.abs(params) <= 2.0)),
    "link_lengths": ("length errors of at most 10 mm", lambda params, radius: np.all(np.abs(params) <= 10.0)),
    # (a little upward allowed: a counterbalanced shoulder can overcompensate)
    "joint_compliance": ("a gravity sag of at most 0.5 deg per metre (and at most 0.1 upward)",
                         lambda params, radius: np.all((params <= 0.5) & (params >= -0.1))),
}


def implausible(name, params, radius, circles=None, names=None):
    """Why fitted ``params`` of effect ``name`` are not physical (text), or None when they are.

    Two tests: the effect's limit (:data:`LIMITS`), and, for an effect whose module defines
    ``contradicted_by(params, radius, circles)`` (``sphere_radius``: a sphere cannot be smaller
    than a circle measured on it), what the data show: ``circles`` is ``(ids, r, sd)``, the
    radius of each sample's measured circle and its 1 sd (mm); without it only the limit is
    tested. ``names``: the parameters' names (a robot effect's depend on the robot model).
    """
    if name in LIMITS:
        what, ok = LIMITS[name]
        if not ok(np.asarray(params, float), radius):
            values = ", ".join(f"{p} = {v:.4g}" for p, v in zip(names or get(name).PARAMS, np.ravel(params)))
            hint = ("a wrong [robot] model or joint columns?" if get(name).KIND == "robot"
                    else "a wrong [profile] side, [sphere] diameter or unit?")
            return f"{name} would need {values}, beyond {what}: it absorbs something else ({hint}), it is not named"
    check = getattr(get(name), "contradicted_by", None) if name in MODULES else None
    if check is not None and circles is not None:
        return check(np.asarray(params, float), radius, circles)
    return None


def needs_diameter(name):
    """Whether data effect ``name`` rebuilds a centre's y from the sphere's radius (a line scanner's
    ``sensor_scale`` and ``sphere_radius``, ``NEEDS_DIAMETER`` in their modules): without ``[sphere]
    diameter`` (a dataset of centres or clouds) it cannot be fitted, and is no candidate."""
    return bool(getattr(get(name), "NEEDS_DIAMETER", False))


def fittable(name, dataset):
    """Whether effect ``name`` can be fitted on ``dataset`` as far as the diameter goes (:func:`needs_diameter`)."""
    return not (needs_diameter(name) and getattr(dataset, "sphere_diameter", 1.0) is None)


def catalogue(kind=None):
    """Effect modules, optionally of one kind."""
    return [get(n) for n in MODULES if kind is None or get(n).KIND == kind]


@functools.lru_cache(maxsize=None)
def _correction_function(name):
    effect = get(name)

    def build():
        import sympy as sp

        xm, ym, zm = sp.symbols("xm ym zm", real=True)
        radius = sp.Symbol("R", positive=True)
        params = sp.symbols(" ".join(f"p_{p}" for p in effect.PARAMS) + ",", real=True)
        corrected = sp.Matrix(effect.correction(xm, ym, zm, radius, params))
        return (xm, ym, zm, radius, *params), list(corrected) + list(corrected.jacobian(params))

    return codegen.numpy_function(codegen.generated_source(f"effect_{name}", build))


def correct(name, xs, radius, params):
    """Corrected centres (N, 3) and their derivative with respect to the parameters (N, 3, k)."""
    effect = get(name)
    xs = np.asarray(xs, float)
    vals = codegen.stack_outputs(_correction_function(name)(xs[:, 0], xs[:, 1], xs[:, 2], radius, *params),
                                 (len(xs),))
    return vals[:, :3], vals[:, 3:].reshape(len(xs), 3, len(effect.PARAMS))
