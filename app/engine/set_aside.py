"""Rows set aside whatever the statistical screening says, and why: a row whose centre columns contradict its own
profile (its two halves cannot both be right), a row whose profile is no arc of the stated sphere (set aside on
load, :mod:`handeye.model.datasets.arcs`), and the geometric cause of a poorly determined centre (a short or
one-sided arc, near the equator, few points) named beside a gross error's statistical reason. calibrate, its
closed-form baselines and diagnose call these same functions, so that they fit the same observations; the
screening itself is :mod:`handeye.app.engine.robust`'s.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.app.present.results import ExcludedSample


def exclude_inconsistent(dataset, unknowns, mask, excluded):
    """Exclude the rows whose centre columns contradict their own profile
    (:func:`handeye.model.datasets.consistency.check_rows`); calibrate, its closed-form baselines and
    diagnose call this one function, so that they fit the same observations.

    Such a row is excluded whatever the statistical screening (and ``--keep-all``) says: its
    two halves cannot both be right, and the profile models and the centre residual would each
    believe a different one. A row the screening excluded too keeps the screening's record,
    its reason extended by the contradiction.

    Parameters
    ----------
    dataset : handeye.model.datasets.dataset.Dataset
    unknowns : {'sensor', 'sensor+sphere'}
    mask : ndarray of bool, shape (N,)
        Samples used so far.
    excluded : list of ExcludedSample
        Their records so far.

    Returns
    -------
    mask : ndarray of bool, shape (N,)
    excluded : list of ExcludedSample
        The rows set aside on load because their profile is no arc of the sphere first
        (:func:`not_arc_records`; not among the N samples), then the inconsistent rows
        (``statistic`` the chi-square on 3 dof of the row against
        itself, ``residual_mm`` and ``robust_residual_mm`` NaN: no fit is involved; the
        screening's numbers where it excluded the row too), then the others.

    Raises
    ------
    CalibrationInputError
        Naming the rows, when more than half of the rows contradict themselves (a systematic slip:
        a shifted ``profile`` column, another campaign's files) or too few rows would remain for
        the unknowns.
    """
    from handeye.app.engine.request import min_measurements
    from handeye.model.datasets import consistency

    aside = not_arc_records(dataset)  # rows set aside on load: no sample, named here with the rest
    check = dataset.once("row_consistency", lambda: consistency.check_rows(dataset))
    if not check.inconsistent:
        return mask, aside + list(excluded)
    keep = np.asarray(mask, bool) & check.consistent
    if len(check.inconsistent) > len(dataset) // 2 or keep.sum() < min_measurements(unknowns):
        raise _contradiction_error(dataset, check, keep, unknowns)
    return keep, aside + _contradiction_records(check.inconsistent, excluded)


def not_arc_records(dataset):
    """The records (list of ExcludedSample) of the rows ``dataset`` set aside on load because their
    profile is no arc of the stated sphere (:mod:`handeye.model.datasets.arcs`): residuals NaN (they
    give no centre), the one-circle test's F and p where it decided."""
    return [ExcludedSample(
        id=b.id, row=b.row, residual_mm=float("nan"), robust_residual_mm=float("nan"), statistic=b.statistic,
        p_bonferroni=b.p_bonferroni,
        reason=f"row {b.row}: its profile {b.file} is not an arc of the {dataset.sphere_diameter:g} mm sphere: {b.reason}")
        for b in getattr(dataset, "not_arcs", ())]


def with_geometry(dataset, excluded):
    """The records ``excluded`` with the geometric cause of each whose profile explains a poorly
    determined centre (:func:`handeye.model.geometry.arc_geometry.causes`: a short or one-sided arc, near
    the equator, few points; named only when its centre's sd along an axis exceeds five times
    the other profiles' median and accounts for its prediction error): in ``geometry`` and
    after the statistical reason."""
    if not excluded or dataset.profiles is None:
        return excluded
    from handeye.model.geometry import arc_geometry

    index = {int(r): k for k, r in enumerate(dataset.rows)}
    records = [e for e in excluded if e.row in index and dataset.profiles[index[e.row]] is not None]
    named = arc_geometry.causes(dataset.profiles, dataset.sphere_diameter / 2, dataset.side,
                                [index[e.row] for e in records], [e.residual_mm for e in records])
    return [dataclasses.replace(e, geometry=named[index[e.row]],
                                reason=f"{e.reason}; its profile explains it: {named[index[e.row]]}")
            if index.get(e.row) in named else e for e in excluded]


def _contradiction_error(dataset, check, keep, unknowns):
    """The CalibrationInputError of :func:`exclude_inconsistent` when too many rows contradict
    themselves (``check`` the consistency check, ``keep`` the rows that would remain)."""
    from handeye.app.common.errors import CalibrationInputError
    from handeye.app.engine.request import min_measurements

    bad, n, need = check.inconsistent, len(dataset), min_measurements(unknowns)
    named = "; ".join(f"row {c.row} ({c.id!r}: {c.disagreement_mm:.3g} mm, {c.sd:.3g} sd)" for c in bad[:12])
    return CalibrationInputError(
        f"{dataset.path / 'measurements.csv'}: {len(bad)} of the {len(check.checked)} rows that give both xs, ys, "
        f"zs and a profile contradict themselves (the profile's circle is not the cut the centre columns predict): "
        f"{named}{' ...' if len(bad) > 12 else ''}; "
        + ("so many point to a systematic slip, not a bad row. " if len(bad) > n // 2 else "")
        + (f"Only {int(keep.sum())} usable row(s) would remain; unknowns {unknowns!r} need {need}. "
           if keep.sum() < need else "")
        + "Check that each row's profile file is its own (a column shifted by one row?) and that the centres "
          "come from the same scans; or leave xs, ys, zs empty to reconstruct the centres from the profiles")


def _contradiction_records(bad, excluded):
    """The records of the self-contradicting rows ``bad`` first (a row the screening excluded too
    keeps its record, both reasons), then the other records of ``excluded``."""
    screened = {e.row: e for e in excluded}
    records = []
    for c in bad:
        also = screened.pop(c.row, None)
        if also is not None:  # a gross error of the centre too: the screening's evidence, both reasons
            records.append(dataclasses.replace(also, reason=f"{also.reason}; and {c.reason}"))
            continue
        records.append(ExcludedSample(
            id=c.id, row=c.row, residual_mm=float("nan"), robust_residual_mm=float("nan"), statistic=c.sd**2,
            p_bonferroni=c.p_bonferroni, reason=c.reason))
    return records + [e for e in excluded if e.row in screened]
