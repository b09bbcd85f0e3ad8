"""Which parameters the data determine: singular values of the (column-scaled) Jacobian.

Columns are scaled to unit norm first, so that mm and degrees do not distort the picture
(a rank statement is unit-free). A scaled singular value below ``rtol`` times the largest
means a direction of the parameters that the residual does not see at all: it is *not
identifiable* and must not be "solved".

Two uses:

* :func:`analyse` at the solution: rank, singular values and condition number reported with
  every calibration.
* :func:`structural` before solving: the Jacobian evaluated on *noise-free* data consistent
  with the start point (the sensor vectors replaced by those the model predicts), so that
  measurement noise cannot mask a degeneracy. Identical poses, or pure translations with the
  sphere centre unknown, give an exactly rank-deficient Jacobian there.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.model.common.rotation import nearest_transform

#: Relative singular value below which a direction counts as not identifiable.
RTOL = 1e-8
#: Inverse condition number (O2) below which a direction counts as badly constrained.
WEAK = 1e-2
#: Inverse condition number below which the poses count as degenerate even though the rank
#: is full: 0.01 mm of noise would move the weakest direction by decimetres (e.g. rotations
#: about the sphere with the sphere always at one sensor point: 1e-6).
NEARLY_SINGULAR = 1e-4


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """Rank analysis of a Jacobian.

    Attributes
    ----------
    rank : int
    n : int
        Number of parameters.
    singular_values : ndarray
        Of the column-scaled Jacobian, descending (dimensionless).
    raw_singular_values : ndarray
        Of the unscaled Jacobian (units of the residual per parameter unit).
    condition : float
        Ratio of largest to smallest scaled singular value (inf when rank-deficient).
    null_directions : list of dict
        For each unidentifiable direction: parameter name -> component (|c| > 0.05 shown).
    weakest_direction : dict
        The direction of the smallest scaled singular value (parameter name -> component).
    observability : dict
        Indices of the scaled Jacobian (m rows, singular values s_1 >= ... >= s_n):
        ``O1 = (s_1 ... s_n)^(1/n) / sqrt(m)`` (Borm & Menq 1991), ``O2 = s_n / s_1`` (inverse
        condition number), ``O3 = s_n`` (minimum singular value), ``O4 = s_n^2 / s_1`` (noise
        amplification index, Nahvi & Hollerbach 1996). Larger is better for all four.
    """

    rank: int
    n: int
    singular_values: np.ndarray
    raw_singular_values: np.ndarray
    condition: float
    null_directions: list
    weakest_direction: dict = dataclasses.field(default_factory=dict)
    observability: dict = dataclasses.field(default_factory=dict)
    names: tuple = ()
    factor: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)
    rows: int = 0
    rtol: float = RTOL

    def turned(self, step):
        """The analysis in the parameters ``p' = step p`` (``step`` (n, n) orthogonal, e.g. the
        rotation about the sensor's own axes: :func:`handeye.model.chain.own_frame.step_to_own`):
        the Jacobian is ``J step^T``, analysed from the triangular factor kept (the column
        scaling makes the analysis change with the parameters' axes, not only turn)."""
        if self.factor is None:
            return self
        return analyse(self.factor @ np.asarray(step, float).T, self.names, self.rtol, rows=self.rows)

    @property
    def full_rank(self):
        return self.rank == self.n

    def describe_null(self):
        """Human-readable text of the unidentifiable directions."""
        return "; ".join(_direction_text(d) for d in self.null_directions)

    def describe_weakest(self):
        """Human-readable text of the direction of the smallest scaled singular value."""
        return _direction_text(self.weakest_direction)

    def to_dict(self):
        """JSON-ready dict (the ``identifiability`` object of a calibration's JSON)."""
        return {
            "rank": self.rank,
            "n": self.n,
            "singular_values": [float(v) for v in self.singular_values],
            "raw_singular_values": [float(v) for v in self.raw_singular_values],
            "condition_number": float(self.condition),
            "not_identifiable": self.null_directions,
            "weakest_direction": self.weakest_direction,
            "observability": self.observability,
        }


def _direction_text(direction):
    return " + ".join(f"{v:+.2f}*{k}" for k, v in direction.items())


#: Above this many rows a model's Jacobian is analysed through its triangular factor.
TALL = 16384


def analyse(jacobian, names, rtol=RTOL, rows=None):
    """Rank, singular values and null directions of ``jacobian`` (m, n); with ``rows`` (its m)
    ``jacobian`` may be the triangular factor R of ``J = Q R`` instead (the same singular
    values, right singular vectors and column norms:
    :meth:`~handeye.model.fit.calibration.CalibrationModel.jacobian_r`)."""
    j = np.asarray(jacobian, dtype=float)
    m = j.shape[0] if rows is None else int(rows)
    raw = np.linalg.svd(j, compute_uv=False)
    norms = np.linalg.norm(j, axis=0)
    _, s, vt = np.linalg.svd(j / np.where(norms > 0, norms, 1.0), full_matrices=False)
    s_full = np.zeros(j.shape[1])
    s_full[: len(s)] = s
    smax = s_full[0] if s_full.size else 0.0
    rank = int(np.sum(s_full > rtol * smax)) if smax > 0 else 0
    rank = min(rank, int(np.sum(norms > 0)))
    null = []
    for k in range(rank, j.shape[1]):
        v = vt[k] if k < vt.shape[0] else np.eye(j.shape[1])[k]
        v = v / v[np.argmax(np.abs(v))]  # the largest entry +1: the sign of an SVD's vector is arbitrary
        null.append({names[i]: round(float(v[i]), 4) for i in np.argsort(-np.abs(v)) if abs(v[i]) > 0.05})
    cond = float(s_full[0] / s_full[-1]) if rank == j.shape[1] and s_full[-1] > 0 else float("inf")
    n = j.shape[1]
    weakest = {}
    if vt.shape[0] == n:
        v = vt[-1] / vt[-1][np.argmax(np.abs(vt[-1]))]  # largest entry +1 (an SVD's sign is arbitrary)
        weakest = {names[i]: round(float(v[i]), 4) for i in np.argsort(-np.abs(v)) if abs(v[i]) > 0.05}
    smin = float(s_full[-1])
    obs = {
        "O1": float(np.exp(np.mean(np.log(np.maximum(s_full, 1e-300)))) / np.sqrt(m)),
        "O2": float(smin / smax) if smax > 0 else 0.0,
        "O3": smin,
        "O4": float(smin**2 / smax) if smax > 0 else 0.0,
    }
    factor = j if rows is not None or m <= n else np.linalg.qr(j, mode="r")
    return Identifiability(rank, n, s_full, raw, cond, null, weakest, obs, tuple(names), factor, m, rtol)


def structural(model, x, rtol=RTOL):
    """Identifiability of ``model`` (a CalibrationModel) at point ``x`` on noise-free data.

    The measured sensor vectors are replaced by those predicted at ``x``:
    ``xs_i = T2^-1 T1_i^-1 c``; the Jacobian there depends on the robot poses alone.
    """
    from handeye.model.fit.calibration import CalibrationModel

    t2 = model.sensor2flange(x)
    if model.rotation == "matrix":  # the nearest rotation, det +1 (an SVD alone may give a reflection)
        t2 = nearest_transform(t2)
    c = model.sphere_centre(x)
    ideal = np.linalg.solve(model.flange2base @ t2, np.append(c, 1.0))[:, :3]
    twin = CalibrationModel(model.flange2base, ideal, c, model.rotation, model.unknowns)
    point = twin.point_from(t2, c)
    if twin.n_meas > TALL:  # the triangular factor, chunk by chunk: not the (3N, n) Jacobian
        return analyse(twin.jacobian_r(point), model.names, rtol, rows=twin.n_meas * twin.m)
    return analyse(twin.jacobian(point), model.names, rtol)


def plate_pose_analysis(flange2base, centre_in_sensor, sensor2flange, plate_pose, centre_in_plate, rtol=RTOL):
    """Rank of the seed's step-2 problem: sensor pose p2 *and* plate pose p3 (12 unknowns).

    The residual sees the plate pose only through ``c = T(p3) x_p'``, a map from six numbers
    to three: its Jacobian ``dc/dp3`` has rank 3, so the 12-unknown Jacobian has rank 9 at most.

    Returns
    -------
    Identifiability
        With parameter names ``tx..wz`` (sensor, local rotation: free of the Euler
        singularity) and ``x3..C3`` (plate).
    """
    from handeye.model.chain import codegen, symbolic
    from handeye.model.fit.calibration import CalibrationModel

    s = symbolic.sphere_centre_from_plate()

    def build():
        return s["p3"] + s["xp"], list(s["c"]) + list(s["jac"])

    gen = codegen.numpy_function(codegen.generated_source("plate_centre", build))
    vals = np.array(gen(*plate_pose, *centre_in_plate), dtype=float)
    c, dc = vals[:3], vals[3:].reshape(3, 6)
    m = CalibrationModel(flange2base, centre_in_sensor, c, "local", "sensor+sphere")
    j = m.jacobian(m.point_from(sensor2flange, c))
    j12 = np.hstack([j[:, :6], j[:, 6:9] @ dc])
    return analyse(j12, m.names[:6] + ["x3", "y3", "z3", "A3", "B3", "C3"], rtol)
