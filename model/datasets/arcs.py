"""Profiles that are no arc of the stated sphere: judged on load, their rows set aside and named.

Every row that names a profile is judged (:mod:`handeye.model.geometry.arc_check`, Bonferroni over
the dataset's profiles): the cleaning found no arc (:mod:`handeye.model.geometry.profile_clean`), its
circle is wider than the sphere or does not give a centre (``r > R``), or its halves are not one
circle (a corner, an edge, a step). One verdict for the dataset:

* a few such rows in a good set -- at most half of the rows with a profile -- are set aside
  (:attr:`handeye.model.datasets.dataset.Dataset.not_arcs`): they give no sphere centre, so they
  are no samples; the calibration names each with its file and row among the excluded samples
  (:func:`handeye.app.engine.set_aside.exclude_inconsistent`), as it names gross errors;
* more than half: the data are not of this sphere (another target, a wrong diameter), and the
  load is refused (:class:`~handeye.model.readers.tables.DatasetError`, the input-error exit 2):
  "the profiles are not arcs of a sphere of diameter D mm: FILE ...", with the diameter hint when
  most of them are circles wider than the sphere.

Why half: the same rule as rows that contradict their own profile (:mod:`handeye.app.engine.robust`):
a few bad rows are a bad row each; a majority is a systematic cause, and excluding it would leave a
calibration on the minority that the data as a whole contradict.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.geometry import arc_check

#: How many non-arc rows a refusal names before it writes "...".
NAMED = 8


@dataclasses.dataclass(frozen=True)
class NotArc:
    """A row whose profile is no arc of the stated sphere.

    Attributes
    ----------
    id : str
    row : int
        Line in ``measurements.csv``.
    file : str
        The profile file, relative to the dataset folder where it lies inside.
    reason : str
        Why, in words.
    statistic : float
        The one-circle test's F (NaN when another check decided).
    p_bonferroni : float
        Its Bonferroni-adjusted p-value (NaN likewise).
    """

    id: str
    row: int
    file: str
    reason: str
    statistic: float = float("nan")
    p_bonferroni: float = float("nan")

    @property
    def wider(self):
        """Its circle is wider than the sphere (a wrong diameter's sign)."""
        return "exceeds the sphere radius" in self.reason


def judge(profiles, problems, radius):
    """The reason each profile is no arc, or None.

    Parameters
    ----------
    profiles : sequence of ndarray (K_i, 2) or None
        The rows' (cleaned) profiles, sensor x, z, mm; None for a row without one.
    problems : sequence of str or None
        A reason found already (the cleaning found no arc, the centre cannot be reconstructed),
        else None.
    radius : float
        The stated sphere's radius R, mm.

    Returns
    -------
    list of (str or None, float, float)
        Per row the reason (None: an arc, or no profile), the F and its Bonferroni p-value.
    """
    n_tests = max(sum(p is not None for p in profiles), 1)
    out = []
    for points, problem in zip(profiles, problems):
        if points is None or problem is not None:
            out.append((problem, float("nan"), float("nan")))
            continue
        v = arc_check.check(points, radius, n_tests)
        out.append((None if v.arc else v.reason, v.f_stat, v.p_value))
    return out


def refusal(bad, diameter):
    """The message of a load refused because most profiles are no arc (module docstring)."""
    named = "; ".join(f"{b.file} (row {b.row}: {b.reason})" for b in bad[:NAMED])
    wider = sum(b.wider for b in bad) > len(bad) / 2
    return (f"the profiles are not arcs of a sphere of diameter {diameter:g} mm: {named}"
            f"{' ...' if len(bad) > NAMED else ''} ({len(bad)} rows); "
            + (f"a profile cannot be wider than the sphere: check [sphere] diameter = {diameter:g} mm in setup.toml "
               "(a radius given for the diameter? inches?)" if wider else
               "is the target a sphere, and the diameter its own? Measure the sphere, or remove the rows"))


def keep_mask(bad_rows, rows):
    """Bool (N,): the rows (lines) not in ``bad_rows``."""
    return ~np.isin(np.asarray(rows, int), np.asarray(sorted(bad_rows), int))
