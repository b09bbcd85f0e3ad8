"""Many starts at once: the state every iterative solver keeps, one row per start.

Every iterative solver of this package is written once, on stacks: the iterates are an
array ``x`` of shape (N, d), the costs ``f`` (N,), the gradients ``g`` (N, n), and each
method's own state (trust radius, damping, inverse-Hessian approximation) one row per start.
Each iteration works on the rows still running (``runs.active()``); a row stops, with its
own status and iteration count, when its own test says so, exactly where a single start
would have stopped. :func:`handeye.solvers.solve` is the N = 1 case of the same code,
:func:`handeye.solvers.solve_many` the general one; there is no second copy of any rule.

A :class:`~handeye.solvers.problem.Problem` whose callables accept stacks of points
(``vectorised=True``, shape (k, d) in, (k, ...) out) is evaluated once per iteration for all
running rows, also when one row runs, so that a start ends bit for bit where it ends alone;
any other problem row by row (same answers, no speed-up).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from handeye.solvers.result import CONVERGED, STATUS_MESSAGES, OptimizeResult, gradient_small
from handeye.solvers.stacks import finite_rows, half_squares, max_abs_rows, transpose_times

RUNNING = -100  # status of a row that has not stopped yet


class Stacked:
    """Evaluations of a :class:`~handeye.solvers.problem.Problem` on stacks of points (k, d)."""

    def __init__(self, problem):
        self.problem = problem
        self.n = problem.n
        self._shapes = {}

    def _map(self, name, fn, *stacks):
        k = len(stacks[0])
        if k == 0:
            known = {"cost": (), "grad": (self.n,), "hessian": (self.n, self.n), "move": stacks[0].shape[1:],
                     "residual": (0,), "jacobian": (0, self.n)}
            return np.zeros((0,) + self._shapes.get(name, known[name]))
        if self.problem.vectorised:
            out = np.asarray(fn(*stacks), dtype=float)
        elif k == 1:
            out = np.asarray(fn(*(s[0] for s in stacks)), dtype=float)[None]
        else:
            out = np.stack([np.asarray(fn(*rows), dtype=float) for rows in zip(*stacks)])
        self._shapes[name] = out.shape[1:]
        return out

    def residual(self, x):
        return self._map("residual", self.problem.residual, x)

    def jacobian(self, x):
        return self._map("jacobian", self.problem.jacobian, x)

    def hessian(self, x):
        return self._map("hessian", self.problem.hessian, x)

    def normal(self, x):
        """``(J^T J, J^T r)`` stacks (k, n, n), (k, n) from the problem's ``normal``."""
        fn = self.problem.normal
        if self.problem.vectorised:
            a, g, _ = fn(x)
            return np.asarray(a, float), np.asarray(g, float)
        parts = [fn(row) for row in x]
        return (np.array([p[0] for p in parts], float).reshape(len(x), self.n, self.n),
                np.array([p[1] for p in parts], float).reshape(len(x), self.n))

    def cost(self, x):
        if not len(x):
            return np.zeros(0)
        if self.problem.objective is not None:
            return self._map("cost", self.problem.objective, x).reshape(len(x))
        return half_squares(self.residual(x))

    def grad(self, x):
        if not len(x):
            return np.zeros((0, self.n))
        if self.problem.gradient is not None:
            return self._map("grad", self.problem.gradient, x)
        return transpose_times(self.jacobian(x), self.residual(x))

    def move(self, x, delta):
        if self.problem.retract is None:
            return x + delta
        return self._map("move", self.problem.retract, x, delta)

    def forward_jacobian(self, x, step):
        """Forward-difference Jacobian through the retraction, ``(r(move(x, h e_j)) - r(x)) / h``."""
        r0 = self.residual(x)
        cols = []
        for j in range(self.n):
            e = np.zeros((len(x), self.n))
            e[:, j] = step
            cols.append((self.residual(self.move(x, e)) - r0) / step)
        return np.stack(cols, axis=-1)


def _counted(counter, name):
    """A :class:`Runs` method ``(x, rows)``: ``Stacked.<name>(x)``, counted once per row in ``counter``."""

    def method(self, x, rows):
        getattr(self, counter)[rows] += 1
        return getattr(self.stacked, name)(x)

    method.__name__ = name
    return method


class Runs:
    """The rows of a batch run: iterates, statuses, counters, and (``trace=True``) histories.

    ``x``, ``f``, ``g`` hold every row's current point, cost and gradient; a solver updates
    the rows it works on and stops rows with :meth:`stop`. Evaluations go through
    :meth:`cost` and friends, which count them per row.
    """

    def __init__(self, stacked, x0, method, trace=False):
        x0 = np.array(x0, dtype=float)
        self.stacked = stacked
        self.method = method
        self.n_rows = len(x0)
        self.x = x0.reshape(self.n_rows, -1) if x0.ndim != 2 else x0
        self.f = np.full(self.n_rows, np.nan)
        self.g = np.full((self.n_rows, stacked.n), np.nan)
        self.status = np.full(self.n_rows, RUNNING)
        self.iterations, self.nfev, self.njev, self.nhev = (np.zeros(self.n_rows, dtype=int) for _ in range(4))
        self.messages = {}
        self.trace = trace
        self.history = [[row.copy()] for row in self.x] if trace else None
        self.traces = {}  # name -> per-row lists (trace=True only)
        self.counts = {}  # name -> per-row counters, reported in extra when > 0

    # -- evaluations, counted per row ---------------------------------------------------
    cost = _counted("nfev", "cost")
    residual = _counted("nfev", "residual")
    grad = _counted("njev", "grad")
    jacobian = _counted("njev", "jacobian")
    normal = _counted("njev", "normal")
    hessian = _counted("nhev", "hessian")

    # -- bookkeeping ----------------------------------------------------------------------
    def active(self):
        """Indices of the rows still running."""
        return np.flatnonzero(self.status == RUNNING)

    def stop(self, rows, mask, status, iteration, message=None):
        """Stop ``rows[mask]`` with ``status`` after ``iteration`` iterations; return the others."""
        if mask is True:
            done, mask = rows, np.ones(len(rows), dtype=bool)
        elif not mask.any():
            return rows
        else:
            done = rows[mask]
        self.status[done] = status
        self.iterations[done] = iteration
        if message is not None:
            self.messages.update(dict.fromkeys(done.tolist(), message))
        return rows[~mask]

    def screened(self, iteration, opts, *arrays):
        """The rows still running after the stops every iteration starts with: a non-finite cost,
        gradient or row of ``arrays`` (N, ...) stops a row with -1, a small gradient
        (:func:`~handeye.solvers.result.gradient_small`) with 1."""
        rows = self.active()
        rows = self.stop(rows, ~finite_rows(self.f[rows], self.g[rows], *(a[rows] for a in arrays)), -1, iteration)
        return self.stop(rows, gradient_small(self.g[rows], self.f[rows], opts), 1, iteration)

    def record(self, rows, x):
        if self.trace:
            for i, xi in zip(rows, x):
                self.history[i].append(np.array(xi, dtype=float))

    def note(self, name, rows, values):
        """Append one value per row to a trace (radius, damping ...); kept with ``trace=True``."""
        if self.trace:
            lists = self.traces.setdefault(name, [[] for _ in range(self.n_rows)])
            for i, v in zip(rows.tolist(), np.broadcast_to(values, rows.shape).tolist()):
                lists[i].append(v)

    def count(self, name, rows):
        self.counts.setdefault(name, np.zeros(self.n_rows, dtype=int))[rows] += 1

    # -- results ---------------------------------------------------------------------------
    def message(self, i):
        return self.messages.get(i, STATUS_MESSAGES.get(int(self.status[i]), "running"))

    def single(self):
        """The first row as an :class:`OptimizeResult` (the single-start answer)."""
        extra = {name: lists[0] for name, lists in self.traces.items()}
        extra.update({name: int(c[0]) for name, c in self.counts.items() if c[0] > 0})
        g = self.g[0]
        return OptimizeResult(
            x=self.x[0].copy(), cost=float(self.f[0]),
            grad_norm=float(np.max(np.abs(g))) if g.size else float("nan"),
            iterations=int(self.iterations[0]), nfev=int(self.nfev[0]), njev=int(self.njev[0]),
            nhev=int(self.nhev[0]), status=int(self.status[0]), message=self.message(0),
            converged=int(self.status[0]) in CONVERGED, method=self.method,
            history=self.history[0] if self.trace else [self.x[0].copy()], extra=extra)

    def result(self):
        """All rows as a :class:`BatchResult`."""
        return BatchResult(
            x=self.x.copy(), cost=self.f.copy(),
            grad_norm=max_abs_rows(self.g),
            iterations=self.iterations.copy(), nfev=self.nfev.copy(), njev=self.njev.copy(),
            nhev=self.nhev.copy(), status=self.status.copy(), method=self.method,
            messages=dict(self.messages))


@dataclasses.dataclass
class BatchResult:
    """Outcome of :func:`handeye.solvers.solve_many`: one row per start.

    Attributes
    ----------
    x : ndarray, shape (N, d)
        Final points.
    cost, grad_norm : ndarray, shape (N,)
        As in :class:`OptimizeResult`.
    iterations, nfev, njev, nhev, status : ndarray of int, shape (N,)
    method : str
    messages : dict
        Row -> message, where a row's message is not its status's (see :meth:`message`).
    """

    x: np.ndarray
    cost: np.ndarray
    grad_norm: np.ndarray
    iterations: np.ndarray
    nfev: np.ndarray
    njev: np.ndarray
    nhev: np.ndarray
    status: np.ndarray
    method: str
    messages: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def empty(cls, d, method):
        """No starts: every array of length 0 (``x`` of shape (0, d))."""
        ints = np.zeros(0, dtype=int)
        return cls(np.zeros((0, d)), np.zeros(0), np.zeros(0), ints, ints, ints, ints, ints, method)

    @property
    def converged(self):
        """Boolean (N,): the row's status is one of :data:`CONVERGED`."""
        return np.isin(self.status, sorted(CONVERGED))

    def __len__(self):
        return len(self.status)

    def message(self, i):
        return self.messages.get(i, STATUS_MESSAGES[int(self.status[i])])

    def to_dict(self):
        """Summary: starts, converged share, and starts per status (with its message)."""
        codes, counts = np.unique(self.status, return_counts=True)
        return {"method": self.method, "starts": len(self), "converged": float(np.mean(self.converged)) if len(self) else 0.0,
                "status": {int(c): {"count": int(n), "message": STATUS_MESSAGES[int(c)]} for c, n in zip(codes, counts)},
                "median_iterations": float(np.median(self.iterations)) if len(self) else 0.0}
