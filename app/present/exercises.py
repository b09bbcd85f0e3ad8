"""The notebooks' exercise checks: right, or wrong with a hint -- never the answer.

Each notebook's first cell makes its checker, and each exercise has a cell of its own that the
student fills in::

    check_exercise = exercises.checker("least_squares")
    ...
    answer = None                 # your turn: replace None with your answer
    check_exercise(2, answer)     # -> "exercise 2: not answered yet (...)"

A check returns a :class:`Verdict`, shown as one line of text; ``verdict.correct`` is True only
for a right answer. The worked solutions end with ``assert check_exercise(N, ...).correct``, so
the test suite, which executes every notebook, drives each check with the solution's own answer.

This module is the answer key (the expected values and their tolerances): a student who wants
to work the exercises should not read it.
"""
from __future__ import annotations

import dataclasses
import numbers

import numpy as np


@dataclasses.dataclass(frozen=True)
class Exercise:
    """One exercise's answer key.

    Attributes
    ----------
    asks : str
        What ``answer`` should be (shown while it is not answered yet).
    expected : object
        The right answer: a number, a sequence of numbers, a (low, high) range, a set of names,
        or an exact value (int, bool, str, tuple), according to ``kind``.
    kind : str
        ``"number"``, ``"vector"``, ``"axis"`` (a direction, either sign), ``"range"``, ``"set"``
        or ``"exact"``.
    atol, rtol : float
        Tolerances of ``"number"``, ``"vector"`` and ``"axis"``.
    hint : str
        Shown with a wrong answer; it points the way and does not contain the answer.
    """

    asks: str
    expected: object
    kind: str = "number"
    atol: float = 0.0
    rtol: float = 0.0
    hint: str = ""


@dataclasses.dataclass(frozen=True)
class Verdict:
    """A check's outcome: ``status`` is ``"not answered yet"``, ``"right"`` or ``"wrong"``.

    Attributes
    ----------
    number : int
        The exercise.
    status : str
        The outcome.
    message : str
        One line for the student (its ``repr``, so a cell ending in a check shows it).
    """

    number: int
    status: str
    message: str

    @property
    def correct(self):
        """True for a right answer."""
        return self.status == "right"

    def __repr__(self):
        return self.message


def _text(value):
    return "".join(str(value).lower().split())


def _numbers(answer):
    """The answer as a float array, or None when it is not numbers."""
    if isinstance(answer, (str, bytes, bool, np.bool_)):
        return None
    try:
        out = np.asarray(answer, dtype=float)
    except (TypeError, ValueError):
        return None
    return out if np.all(np.isfinite(out)) else None


def _matches(key, answer):
    """Whether ``answer`` is right by ``key``'s rule; None when it has the wrong form."""
    if key.kind in ("number", "vector", "axis", "range"):
        got, want = _numbers(answer), np.asarray(key.expected, dtype=float)
        if key.kind == "range":
            return None if got is None or got.ndim else bool(want[0] <= got <= want[1])
        if got is None or got.shape != want.shape:
            return None
        if key.kind == "axis":
            norm = np.linalg.norm(got)
            return bool(norm > 0 and abs(got @ want) / (norm * np.linalg.norm(want)) >= 1 - key.atol)
        return bool(np.allclose(got, want, atol=key.atol, rtol=key.rtol))
    if key.kind == "set":
        if isinstance(answer, (str, bytes)) or not hasattr(answer, "__iter__"):
            return None
        return {_text(a) for a in answer} == {_text(e) for e in key.expected}
    if isinstance(key.expected, str):
        return _text(answer) == _text(key.expected) if isinstance(answer, str) else None
    if isinstance(key.expected, bool):
        return answer is key.expected or (isinstance(answer, np.bool_) and bool(answer) is key.expected)
    if isinstance(key.expected, tuple):
        return None if not hasattr(answer, "__len__") or len(answer) != len(key.expected) else (
            all(bool(a) is e if isinstance(e, bool) else a == e for a, e in zip(answer, key.expected)))
    if isinstance(answer, numbers.Real) and not isinstance(answer, (bool, np.bool_)):
        return float(answer) == key.expected  # an int key: 32.0 from an array is 32
    return None


def check(notebook, number, answer):
    """Check the student's ``answer`` to exercise ``number`` of ``notebook``.

    Parameters
    ----------
    notebook : str
        The notebook's name without ``.ipynb`` (a key of :data:`EXERCISES`).
    number : int
        The exercise, counted from 1 as in the notebook's list.
    answer : object
        The student's answer; None means not answered yet.

    Returns
    -------
    Verdict
        Right, wrong (with the exercise's hint) or not answered yet (with what is asked); the
        message never states the expected answer.
    """
    key = EXERCISES[notebook][number - 1]
    if answer is None:
        return Verdict(number, "not answered yet", f"exercise {number}: not answered yet -- set answer to {key.asks}")
    ok = _matches(key, answer)
    if ok is None:
        return Verdict(number, "wrong", f"exercise {number}: wrong form -- the answer should be {key.asks}")
    if ok:
        return Verdict(number, "right", f"exercise {number}: right")
    return Verdict(number, "wrong", f"exercise {number}: not yet right -- hint: {key.hint}")


def checker(notebook):
    """The check function of one notebook.

    Parameters
    ----------
    notebook : str
        The notebook's name without ``.ipynb``.

    Returns
    -------
    callable
        ``check_exercise(number, answer) -> Verdict`` (see :func:`check`).

    Raises
    ------
    KeyError
        When the notebook has no answer keys.
    """
    if notebook not in EXERCISES:
        raise KeyError(f"no exercises for {notebook!r}; known: {', '.join(sorted(EXERCISES))}")

    def check_exercise(number, answer):
        return check(notebook, number, answer)

    check_exercise.__doc__ = f"Check an answer to one exercise of {notebook}.ipynb (None: not answered yet)."
    return check_exercise


_SHARE = "a fraction between 0 and 1"

#: notebook -> its exercises' answer keys, in the order of the notebook's list.
EXERCISES = {
    "optimality_conditions": (
        Exercise("the condition number lambda_2 / lambda_1 of the Hessian at the minimum steepest descent "
                 "approaches more slowly (a number)", 1.047, rtol=0.005,
                 hint="take np.linalg.eigvalsh of testfunction.hessian at each minimiser; the slower one has the larger ratio"),
        Exercise("the largest |2-D cross product of x - a and x - b| over the three stationary points (a number)",
                 0.0, atol=1e-8, hint="u = p.x - a, v = p.x - b; the cross product is u[0] * v[1] - u[1] * v[0]"),
        Exercise("the set of p in {3, 4, 5, 6} for which the origin is a minimiser", {4, 6}, kind="set",
                 hint="evaluate f_p at (0, -t) for a small t > 0 and compare with f_p(0, 0)"),
        Exercise("the point (x1, x2) where Newton's method from (0.105, -0.205) ends", (0.169047, -0.246430),
                 kind="vector", atol=1e-4, hint="solvers.solve(handeye.testfunction_problem(), printed, 'newton').x"),
        Exercise("the radius of the largest convex disc around the global minimiser (a number, to 0.01)", 0.56, atol=0.01,
                 hint="f is convex where the Hessian's smallest eigenvalue is positive; bisect on the radius of circles"),
    ),
    "solver_paths": (
        Exercise(f"the share of the 41 x 41 starts from which plain Newton ends at the saddle ({_SHARE})", 0.114, atol=0.004,
                 hint="count the end points within 1e-6 of the saddle, then divide by the number of starts (41**2)"),
        Exercise("the measured contraction factor e_(k+1) / e_k of the fixed step 2 / (lambda_1 + lambda_2) near x*",
                 0.0229, rtol=0.02,
                 hint="iterate x - alpha * gradient(x) from (1.2, 1.1) a few times and divide successive errors"),
        Exercise("the index k of the first iteration whose step is the full Newton step (an int)", 3, kind="exact",
                 hint="compare h[k + 1] - h[k] with -solve(hessian(h[k]), gradient(h[k])) for each k of runs['tr'].history"),
        Exercise("the number of GN iterations from (-0.7, -1.6) until the error to b is below 1e-12 (an int)", 4, kind="exact",
                 hint="build a Problem with the residual rows 2: and count len(run.history) - 1"),
    ),
    "constrained_optimality": (
        Exercise("the rank of the 9 x 12 Jacobian of all nine entries of R^T R - I at x* (an int)", 6, kind="exact",
                 hint="the nine entries of a symmetric matrix hold each off-diagonal constraint twice"),
        Exercise("the central-difference slope d f* / d eps of the re-solved optimal cost (a number)", 1.112058, rtol=1e-3,
                 hint="shift lbg and ubg of the first constraint by +-eps, re-solve with IPOPT, divide the cost change by 2 eps"),
        Exercise("the dimension of the tangent space of the constraints at x* (an int)", 6, kind="exact",
                 hint="twelve unknowns, and count the independent constraints"),
        Exercise("a pair (Hess L positive definite?, Hess f positive definite?) of bools at x*", (True, True), kind="exact",
                 hint="look at np.linalg.eigvalsh of the 12 x 12 matrices themselves, not only on the tangent space"),
        Exercise("the move of the sensor position (mm) when one measured centre coordinate changes by 0.1 mm (a number)",
                 0.013705, rtol=0.02, hint="perturb xs_r[0, 0] by 0.1 mm, re-solve with opti_calibration, "
                 "and take the distance of the two positions"),
    ),
    "hand_eye_calibration": (
        Exercise("the text 'A + C' or 'A - C': the combination the rotation depends on at B = -90 deg", "A + C",
                 kind="exact", hint="R_y(-90 deg) maps the x axis onto the z axis: write R_y(-90) R_x(C) as R_?(C) R_y(-90)"),
        Exercise("the log-log slope of sigma_min / sigma_max against |B + 90 deg| (a number)", 1.007, atol=0.03,
                 hint="np.polyfit(np.log(bs + 90), np.log(relative_smallest_sv values), 1)[0] over B near -90"),
        Exercise("the three products sd_x * sqrt(N) in um for N = 8, 16, 32 poses", (29.0, 31.0, 30.0), kind="vector",
                 rtol=0.03, hint="replicates(0.025, n, count=1) returns the predicted covariance; sd x is sqrt(cov[0, 0]) in mm"),
        Exercise("the unit vector (3 numbers) of the long axis of the translation's confidence ellipsoid",
                 (-0.058, 0.988, 0.143), kind="axis", atol=2e-4,
                 hint="the eigenvector of the largest eigenvalue of cov[:3, :3] (np.linalg.eigh sorts them ascending)"),
    ),
    "least_squares": (
        Exercise("the set of parameter names whose component in the weakest direction exceeds 0.3 in size",
                 {"tx", "tz"}, kind="set",
                 hint="np.linalg.eigh(jtj + s): the first column of the eigenvectors, named by allm.names"),
        Exercise("the measured number of GN iterations to gain six digits at sigma = 10 mm (an int)", 12, atol=1,
                 hint="the first k at which the error falls below 1e-6 times the first error"),
        Exercise("the largest ratio e_(k+1) / e_k^2 of Gauss-Newton on the noise-free simulation (a number)", (5e-4, 0.01),
                 kind="range",
                 hint="ratios of successive errors to the previous error squared, leaving out rounding-level errors"),
        Exercise("the three translation sds (mm) from sigma^2 H^-1 at the large-residual minimum", (361.8, 289.1, 448.5),
                 kind="vector", rtol=0.01,
                 hint="sigma^2 = 2 cost / (93 - 6) and H = jtj + s; the square roots of the first 3 diagonal entries"),
    ),
    "linear_versus_nonlinear": (
        Exercise("the largest |vec(AXB) - (A kron B^T) vec X| for random A, X, B (a number)", 0.0, atol=1e-12,
                 hint="numpy's ravel is row-major; use np.kron(A, B.T)"),
        Exercise("the Frobenius distance |R_best - M| for M = default_rng(3).normal(size=(3, 3)) (a number)",
                 2.8764, rtol=1e-4, hint="R_best = U diag(1, 1, det(U V^T)) V^T from the SVD of M"),
        Exercise("the largest distance (mm) over the five replicates between Newton's end and the NLS solution",
                 (0.0, 1e-6), kind="range",
                 hint="start plain Newton at model.point_from(classics.kim_cho(f2b, xs).sensor2flange)"),
    ),
    "discrepancy_thesis_real": (
        Exercise("the shift (3 numbers, mm) of the freed sphere centre from the taught one", (-5.635, 1.682, 2.943),
                 kind="vector", atol=0.02,
                 hint="handeye.calibrate(data, unknowns='sensor+sphere').sphere_centre - data.sphere_centre"),
        Exercise("the set of effect names the diagnosis names in the end", {"sphere_center"}, kind="set",
                 hint="a nominee is named only when its refit is confirmed: read result.effects, not result.tests"),
        Exercise("the sd (mm) of an extra error, in quadrature with the nominal 0.05 mm, that explains the fit (a number)",
                 0.342, atol=0.003, hint="sqrt(sigma_after^2 - sigma_nominal^2) with result.sigma_after_mm"),
        Exercise("the tilt range (deg, one of 2, 4, 8, 16, 32) from which the part outside the span exceeds the noise",
                 32, kind="exact", hint="compare the RMS of the part outside the span with the noise for each tilt range"),
    ),
}
