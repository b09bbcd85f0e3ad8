"""The residuals of a calibration, one row per measurement: :class:`SampleResidual`, and
:class:`ResidualTable`, which holds a million rows as columns and writes their JSON column-wise
(the ``residuals`` of :class:`handeye.app.present.results.CalibrationResult`).
"""
from __future__ import annotations

import dataclasses
import json
from json.encoder import encode_basestring_ascii as quote

import numpy as np

from handeye.app.common.jsonio import finite_json
from handeye.app.present.result_parts import _list


@dataclasses.dataclass(frozen=True)
class SampleResidual:
    """Residual of one measurement at the calibration.

    Attributes
    ----------
    id : str
    row : int
        Line of the measurement in ``measurements.csv``.
    vector : ndarray, shape (3,)
        Predicted minus known sphere centre, robot base, mm.
    norm : float
        ``|vector|``, mm.
    used : bool
        False when excluded as a gross error.
    loo_error_mm : float or None
        Leave-one-out prediction error (None when not computed or not used).
    """

    id: str
    row: int
    vector: np.ndarray
    norm: float
    used: bool
    loo_error_mm: float | None = None

    def to_dict(self):
        return {"id": self.id, "row": int(self.row), "vector": _list(self.vector), "norm": float(self.norm),
                "used": bool(self.used), "loo_error_mm": self.loo_error_mm}


class ResidualTable:
    """The residuals of every measurement as columns: a read-only sequence of
    :class:`SampleResidual` (``len``, indexing, iteration) that holds a million rows in a few
    arrays instead of a million objects, and writes its JSON without building them.

    Parameters
    ----------
    ids : sequence of str, length N
    rows : array_like of int, shape (N,)
        Lines in ``measurements.csv``.
    vectors : array_like, shape (N, 3)
        Predicted minus known sphere centre, robot base, mm.
    norms : array_like, shape (N,)
        ``|vector|``, mm.
    used : array_like of bool, shape (N,)
    loo : array_like, shape (N,), optional
        Leave-one-out prediction errors, mm; NaN (or absent) where not computed.
    """

    def __init__(self, ids, rows, vectors, norms, used, loo=None):
        self.ids = list(ids)
        self.rows = np.asarray(rows, int)
        self.vectors = np.asarray(vectors, float).reshape(-1, 3)
        self.norms = np.asarray(norms, float)
        self.used = np.asarray(used, bool)
        self.loo = np.full(len(self.ids), np.nan) if loo is None else np.asarray(loo, float)

    def __len__(self):
        return len(self.ids)

    def _one(self, k):
        lo = self.loo[k]
        return SampleResidual(self.ids[k], int(self.rows[k]), self.vectors[k], float(self.norms[k]),
                              bool(self.used[k]), float(lo) if np.isfinite(lo) else None)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self._one(i) for i in range(*k.indices(len(self)))]
        return self._one(range(len(self))[k])

    def __iter__(self):
        return (self._one(k) for k in range(len(self)))

    def json_rows(self):
        """Strict compact JSON of each row's dict (same keys and numbers as :meth:`SampleResidual.to_dict`;
        non-finite numbers as null), formatted column-wise: a list of N strings."""
        def numbers(a):  # repr: the shortest text that parses to the same float; one finiteness test per column
            out = list(map(float.__repr__, a.tolist()))
            for k in np.flatnonzero(~np.isfinite(a)).tolist():
                out[k] = "null"
            return out

        x, y, z = (numbers(self.vectors[:, i]) for i in range(3))
        used = ["true" if u else "false" for u in self.used.tolist()]
        return [f'{{"id":{quote(i)},"row":{r},"vector":[{a},{b},{c}],"norm":{n},"used":{u},"loo_error_mm":{lo}}}'
                for i, r, a, b, c, n, u, lo in zip(self.ids, self.rows.tolist(), x, y, z, numbers(self.norms), used,
                                                    numbers(self.loo))]


def residuals_json(residuals):
    """Compact JSON text of the residual list, one row a line (a report of a million rows stays
    readable line by line and is written in seconds)."""
    rows = (residuals.json_rows() if isinstance(residuals, ResidualTable)
            else [json.dumps(finite_json(r.to_dict()), separators=(",", ":"), allow_nan=False) for r in residuals])
    return "[\n" + ",\n".join(rows) + "\n]" if rows else "[]"
