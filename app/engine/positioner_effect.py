"""``positioner_axes``: the positioner's axes as an effect of the discrepancy workflow.

The seed blames part of what remains after calibration on the robot-table calibration its cell
lacked (chapter 4.3). For a sphere on a positioner, :func:`handeye.app.engine.diagnose.diagnose`
asks first whether the set-up axes are that missing effect:

1. The base model: the sensor pose and the sphere centre, the axes as set up
   (:class:`handeye.model.fit.cell.CellModel`), on the screened samples. The centre is free here so
   that a centre given wrong is left to the catalogue's ``sphere_center``, not taken for the axes.
2. The extended model: the sensor, the centre and the axes (4 parameters per axis: two tilts of the direction,
   two shifts of the point normal to it), when the axis angles determine them (else the effect
   is not measurable here, and is not named).
3. The same three tests as every catalogue effect (:func:`handeye.app.engine.diagnose._confirmed`):
   the F test of the reduction in SSR at the level ``alpha``, Delta BIC < 0, and a lower 5-fold
   held-out prediction error. When all agree the effect is named with its parameters and 1-sd
   (relative to the set-up axes), and the rest of the procedure runs at the refined axes.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.common.errors import CalibrationInputError
from handeye.app.engine import cell_stage
from handeye.app.present.result_parts import NamedEffect
from handeye.model.common.statistics import f_survival
from handeye.model.fit.cell import normals

#: Folds of the held-out prediction error (as the catalogue's).
FOLDS = 5
#: The parts both models fit: the sphere centre too, so that a centre given wrong (the catalogue's
#: ``sphere_center``, named in the next steps) is not taken for the axes.
BASE = ("sensor", "sphere")


@dataclasses.dataclass(frozen=True)
class AxesFinding:
    """The axes named as an effect: the dataset at the refined axes, the named effect, the fits'
    summaries (``rms_mm``, ``chi2_dof``, ``sigma_mm``, ``heldout_rms_mm``) and the F test's p."""

    dataset: object
    effect: NamedEffect
    before: dict
    after: dict
    p_value: float


def _fit(dataset, free, sensor, mask, centre=None):
    """The cell fit with the turning axes (:func:`handeye.app.engine.cell_stage.turning_axes`) free."""
    centre = dataset.sphere_centre if centre is None else centre
    return cell_stage.fit(dataset, free, cell_stage.Start(sensor, centre), mask, axes=cell_stage.turning_axes(dataset))


def heldout_rms(dataset, free, fitted, mask):
    """RMS prediction error (mm) of held-out samples, 5-fold cross-validation over ``mask``."""
    idx = np.where(mask)[0]
    folds = np.array_split(np.random.default_rng(0).permutation(idx), min(FOLDS, len(idx)))
    errs = []
    start = dataset.mounts.at(fitted.axes) if fitted.axes else dataset.mounts
    for fold in folds:
        train = mask.copy()
        train[fold] = False
        f = _fit(dataclasses.replace(dataset, mounts=start), free, fitted.sensor, train, fitted.centre)
        e = f.prob.chain(f.structure, f.x, f.params, fold)[0]
        errs.append(np.sum(e**2, axis=1))
    return float(np.sqrt(np.mean(np.concatenate(errs))))


def _summary(dataset, free, fitted, mask, sigma):
    r = fitted.residual()
    return {"rms_mm": float(np.sqrt(np.sum(r**2) / mask.sum())), "chi2_dof": float(fitted.sigma**2 / sigma**2),
            "sigma_mm": fitted.sigma, "heldout_rms_mm": heldout_rms(dataset, free, fitted, mask)}


def axis_offsets(nominal, fitted):
    """Per axis the chart coordinates of the fitted axis relative to the set-up one: tilts (deg)
    about the set-up direction's two normals and shifts (mm) of the point normal to it, with
    their 1-sd from the fit's covariance (the chart at the solution, nearly the same basis)."""
    params, sd = {}, {}
    names, cov = fitted.names, fitted.covariance
    for nom, axis in zip(nominal, fitted.axes):
        if f"{nom.name}_tilt1" not in names:
            continue  # held: it did not turn
        e1, e2 = normals(nom.direction)
        d, along = axis.direction, axis.direction @ nom.direction  # along < 0: the axis turned round
        shift = axis.point - nom.point
        values = (np.degrees(np.arctan2(d @ e1, along)), np.degrees(np.arctan2(d @ e2, along)), shift @ e1, shift @ e2)
        for key, value, unit in zip(("tilt1", "tilt2", "shift1", "shift2"), values, ("deg", "deg", "mm", "mm")):
            name = f"{nom.name}_{key}"
            params[f"{name}_{unit}"] = float(value)
            k = names.index(name)
            s = float(np.sqrt(max(cov[k, k], 0.0))) if cov is not None else float("nan")
            sd[f"{name}_{unit}"] = float(np.degrees(s)) if unit == "deg" else s
    return params, sd


def examine(dataset, mask, sensor, sigma, alpha, centre=None):
    """The axes tested as the missing effect (module docstring): an :class:`AxesFinding`, or None
    when they are not measurable here or the tests do not all agree. Only the axes that turn
    (at least three angles) are estimated; ``centre`` (table frame) starts the fit, default the
    setup's."""
    if not cell_stage.turning_axes(dataset):
        return None
    try:
        base = _fit(dataset, BASE, sensor, mask, centre)
        new = _fit(dataset, BASE + ("positioner",), base.sensor, mask, base.centre)
    except CalibrationInputError:
        return None  # the axis angles do not determine the axes: not measurable, never named
    m, k = 3 * int(mask.sum()), new.n - base.n
    ssr_base, ssr_new = base.sigma**2 * (m - base.n), new.sigma**2 * (m - new.n)
    if ssr_new >= ssr_base or m - new.n <= 0:
        return None
    p_f = f_survival(((ssr_base - ssr_new) / k) / (ssr_new / (m - new.n)), k, m - new.n)
    d_bic = m * np.log(ssr_new / ssr_base) + k * np.log(m)
    if not (p_f < alpha and d_bic < 0):
        return None
    before = _summary(dataset, BASE, base, mask, sigma)
    after = _summary(dataset, BASE + ("positioner",), new, mask, sigma)
    if after["heldout_rms_mm"] >= before["heldout_rms_mm"]:
        return None
    params, sd = axis_offsets(dataset.mounts.axes, new)
    refined = dataclasses.replace(dataset, mounts=dataset.mounts.at(new.axes))
    note = ("the refined axes, for [positioner] in setup.toml (or calibrate with --unknowns "
            "sensor+sphere+positioner): " + toml_axes(refined.mounts.axes))
    return AxesFinding(refined, NamedEffect("positioner_axes", params, sd, note), before, after, p_f)


def toml_axes(axes):
    """``axes = [...]`` as setup.toml writes it (mm, unit directions)."""
    def vec(v, digits):
        return "[" + ", ".join(f"{x:.{digits}f}" for x in v) + "]"

    return "axes = [" + ", ".join(f'{{ name = "{a.name}", point = {vec(a.point, 4)}, direction = {vec(a.direction, 8)} }}'
                                  for a in axes) + "]"


def with_positioner_hint(result, dataset, parts, alpha):
    """A result with the positioner held at its set-up axes and residuals beyond the stated noise:
    when the axes, estimated too, explain the residuals (the tests of
    :func:`handeye.app.engine.positioner_effect.examine`), the pose at the set-up axes is not right
    -- the result is refused (not converged: exit 1) with that evidence and the option that
    calibrates them; otherwise a warning says the axes may be the cause."""
    test = result.noise_test
    if dataset.mounts.sphere != "positioner" or "positioner" in (parts or "") or test is None or test.passed:
        return result
    more = "+".join(p for p in ("sensor", "sphere", "positioner") if p in (parts or "").split("+") or p == "positioner")
    found = examine(dataset, cell_stage.mask_of(result), result.sensor2flange, dataset.noise_centre_mm, alpha,
                    centre=result.sphere_centre) if cell_stage.solved(result) else None
    if found is None:
        hint = (f"the positioner's axes are held as set up ([positioner] axes in {dataset.path / 'setup.toml'}); "
                f"residuals {test.ratio:.3g} x the stated noise may be their error: calibrate them with --unknowns {more}")
        return dataclasses.replace(result, warnings=[*result.warnings, hint])
    moved = ", ".join(f"{k} {v:+.3g}" for k, v in found.effect.parameters.items())
    refusal = (f"not a calibration: the positioner's set-up axes are off ({moved}): estimated too, they explain the "
               f"residuals (RMS {found.before['rms_mm']:.3g} -> {found.after['rms_mm']:.3g} mm, held-out "
               f"{found.before['heldout_rms_mm']:.3g} -> {found.after['heldout_rms_mm']:.3g} mm, F test p = "
               f"{found.p_value:.2g}), so the pose at the set-up axes is wrong; calibrate with --unknowns {more} "
               "(or correct [positioner] axes: handeye diagnose prints them)")
    return result.refused(refusal)
