"""The CBF QP and its solver: Clarabel or OSQP through Drake's ``MathematicalProgram``, or a
compiled dual active-set method (``active_set``) with Clarabel where it cannot answer.

For k robots solved jointly (u stacked ``[a_0, omega_0, a_1, ...]``, m/s^2 and rad/s)::

    min  sum_i |u_i - u_nom_i|^2 + W sum_r s_r
    s.t. G u + s >= b,  s >= 0,  lo <= u <= hi

The slack ``s`` (one per safety row, linear exact penalty ``W``: zero whenever the hard rows are
feasible) only relaxes safety rows; the input bounds are hard, so the QP is always feasible.

Per call (``CbfQp.solve``): when the nominal clipped to the bounds meets every row it is the
optimum and no solver runs; otherwise rows that the bounds alone already satisfy are dropped
(they cannot change the optimum) and the rest are padded with trivial rows to a multiple of 4,
so that one ``MathematicalProgram`` per (robots, padded rows) is built once and afterwards only
its coefficients and bounds are updated.
"""

import math
import time
from dataclasses import dataclass

import numba
import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver, SolverOptions

from mrta_drake.control.active_set import SOLVED, UNMET, solve_qps
from mrta_drake.errors import require_choice, require_positive
from mrta_drake.stack.compiled_helper import compiled_helper

SOLVERS = ("clarabel", "osqp", "active_set")
_PAD = 4  # row counts are padded to a multiple of this so that few programs are built
SLACK_IN_USE = 1e-6  # scaled rows, m/s^2: slack above this means the rows were not all met


@dataclass(frozen=True)
class QpParams:
    """The QP ``solver`` and the ``slack_weight`` W, the linear penalty per unit of slack
    (scaled rows, m/s^2). ``active_set`` (the default) solves a QP whose rows can all be met
    without slack by the compiled dual active-set method of ``active_set`` (its exact
    optimum, ~3 us instead of ~100 us) and the others (rows that must be relaxed) with
    Clarabel; ``clarabel`` (interior point) and ``osqp`` (ADMM) run every QP through Drake.
    ``active_set`` changes trajectories in their last bits and beyond against ``clarabel``
    (docs/benchmarks.md, "Fifth round"; why it is the default: docs/control.md)."""

    solver: str = "active_set"
    slack_weight: float = 1e4

    def __post_init__(self):
        require_choice(self, "solver", SOLVERS)
        require_positive(self, "slack_weight")


@dataclass(frozen=True)
class QpSolution:
    """``u`` (k, 2) inputs ``[a, omega]``; ``slack`` (m,) per safety row (scaled units, m/s^2)
    and its largest, ``max_slack`` (0 for none); ``success`` False when the solver failed
    (``u`` is then meaningless); ``solve_time`` s of wall-clock time (the solver runs on the
    calling thread); ``solved`` False when the clipped nominal was already optimal (no
    solver call)."""

    u: np.ndarray
    slack: np.ndarray
    success: bool
    solve_time: float
    solved: bool = True
    max_slack: float = 0.0


class _Program:
    """One MathematicalProgram for k robots and m safety rows, built once; each solve only
    updates coefficients and bounds."""

    def __init__(self, k: int, m: int, slack_weight: float):
        self.prog = MathematicalProgram()
        self.u = self.prog.NewContinuousVariables(2 * k, "u")
        self.s = self.prog.NewContinuousVariables(m, "s")
        self.hessian = 2.0 * np.eye(2 * k)
        self.cost = self.prog.AddQuadraticCost(self.hessian, np.zeros(2 * k), self.u,
                                               is_convex=True)
        self.box = self.prog.AddBoundingBoxConstraint(np.zeros(2 * k), np.zeros(2 * k), self.u)
        self.upper = np.full(m, np.inf)
        self.prog.AddLinearCost(np.full(m, slack_weight), 0.0, self.s)
        self.prog.AddBoundingBoxConstraint(np.zeros(m), self.upper, self.s)
        self.rows = self.prog.AddLinearConstraint(
            np.hstack([np.zeros((m, 2 * k)), np.eye(m)]), np.zeros(m), self.upper,
            np.concatenate([self.u, self.s]))
        # The decision variables are u, then s: a solution vector reads [u, s].
        self.cost_evaluator, self.box_evaluator, self.rows_evaluator = (
            binding.evaluator() for binding in (self.cost, self.box, self.rows))


@dataclass(frozen=True)
class LoadedQp:
    """A QP over k robots as its program takes it (``load_qp``): whether its rows are
    ``finite`` (if not, it fails without a solve); of its m safety rows those ``kept``
    (indices), padded to ``size`` rows; and ``data``, the flat block ``load_qp`` wrote: the
    linear cost (2k,), the bounds ``lower`` and ``upper`` (2k,) each, the rows' lower bounds
    (size,) and the rows' matrix [A | I] (size, 2k + size)."""

    k: int
    m: int
    finite: bool
    kept: np.ndarray
    size: int
    data: np.ndarray


class CbfQp:
    """Solves the CBF QP above with Clarabel or OSQP (through Drake), reusing one program per
    problem size (k robots, m rows), or with the compiled active-set method where its rows
    can all be met (``active_set``)."""

    def __init__(self, solver: str = "clarabel", slack_weight: float = 1e4):
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        self.solver_name = solver
        self.slack_weight = float(slack_weight)
        self._solver = OsqpSolver() if solver == "osqp" else ClarabelSolver()
        self._active_set = solver == "active_set"
        self._options = SolverOptions()
        if solver == "osqp":
            # Drake's defaults (1e-5) leave visible slack on tight rows; polish snaps to the
            # active set.
            for name, value in (("eps_abs", 1e-7), ("eps_rel", 1e-7), ("polishing", 1),
                                ("max_iter", 20000)):
                self._options.SetOption(OsqpSolver.id(), name, value)
        self._programs: dict[tuple[int, int], _Program] = {}

    def solve(self, u_nominal, G, b, lower, upper, *,
              unless_unmet: bool = False) -> QpSolution | None:
        """``u_nominal``, ``lower``, ``upper`` (k, 2); rows ``G`` (m, 2k) u >= ``b`` (m,)
        (``unless_unmet`` as for ``solve_loaded``)."""
        u_nom = np.asarray(u_nominal, dtype=float).reshape(-1)
        lo = np.asarray(lower, dtype=float).reshape(-1)
        hi = np.asarray(upper, dtype=float).reshape(-1)
        G = np.asarray(G, dtype=float)
        b = np.asarray(b, dtype=float)
        k, m = len(u_nom) // 2, len(b)
        start = time.perf_counter()
        clipped, finite, optimal, kept, size, data = _prepare(u_nom, G, b, lo, hi)
        if finite and optimal:
            return QpSolution(clipped.reshape(k, 2), np.zeros(m), True,
                              time.perf_counter() - start, solved=False)
        return self.solve_loaded(LoadedQp(k, m, finite, kept, size, data), start,
                                 unless_unmet=unless_unmet)

    def solve_loaded(self, qp: LoadedQp, start: float | None = None, *,
                     unless_unmet: bool = False) -> QpSolution | None:
        """The solution of a QP loaded by ``load_qp`` (its solve time counted from
        ``start``, a ``time.perf_counter()``; None: now). With ``unless_unmet`` and the
        ``active_set`` solver: None, without a Clarabel solve, when the active set finds
        that no input within the bounds meets every row (the slack is in use)."""
        start = time.perf_counter() if start is None else start
        k = qp.k
        if not qp.finite:
            return QpSolution(np.zeros((k, 2)), np.zeros(qp.m), False,
                              time.perf_counter() - start)
        if self._active_set:
            u, status = np.empty((k, 2)), np.empty(1, np.int64)
            solve_qps(qp.data, np.array([0, len(qp.data)]), np.array([len(qp.kept)]),
                      np.array([qp.size]), np.arange(k), np.array([0, k]), self.slack_weight,
                      u, status)
            if status[0] == SOLVED:
                return QpSolution(u, np.zeros(qp.m), True, time.perf_counter() - start)
            if unless_unmet and status[0] == UNMET:
                return None
        return self.solve_with_slack(qp, start)

    def solve_all(self, data, data_start, kept_count, sizes, members, group_start,
                  u) -> np.ndarray | None:
        """With the ``active_set`` solver, the loaded QPs ``data[data_start[g]:data_start[g +
        1]]`` (as ``TickQps`` holds them) in one compiled call (``active_set.solve_qps``):
        each ``SOLVED`` one's answer written to its robots' rows of ``u`` (N, 2), the same
        as ``solve_loaded`` returns; the QPs' ``status`` (G,) (``active_set.NOT_LOADED``
        ... ``UNMET``). None with another solver (nothing done)."""
        if not self._active_set:
            return None
        status = np.empty(len(data_start) - 1, np.int64)
        solve_qps(data, data_start, kept_count, sizes, members, group_start,
                  self.slack_weight, u, status)
        return status

    def solve_with_slack(self, qp: LoadedQp, start: float) -> QpSolution:
        """The QP loaded in ``qp`` with its slack, by Clarabel or OSQP (the ``active_set``
        solver's QPs that need the slack: Clarabel); solve time counted from ``start``."""
        k, size, data = qp.k, qp.size, qp.data
        n = 2 * k
        lo, hi = data[n:2 * n], data[2 * n:3 * n]
        program = self._programs.get((k, size))
        if program is None:
            program = self._programs[(k, size)] = _Program(k, size, self.slack_weight)
        program.cost_evaluator.UpdateCoefficients(program.hessian, data[:n], 0.0, True)
        program.box_evaluator.set_bounds(lo, hi)
        program.rows_evaluator.UpdateCoefficients(
            data[3 * n + size:].reshape(size, n + size), data[3 * n:3 * n + size],
            program.upper)
        result = self._solver.Solve(program.prog, None, self._options)
        elapsed = time.perf_counter() - start
        if not result.is_success():
            return QpSolution(np.zeros((k, 2)), np.zeros(qp.m), False, elapsed)
        x = result.GetSolution()
        slack = np.zeros(qp.m)
        slack[qp.kept] = np.maximum(x[n:n + len(qp.kept)], 0.0)
        return QpSolution(np.minimum(np.maximum(x[:n], lo), hi).reshape(k, 2), slack, True,
                          elapsed, max_slack=float(slack.max(initial=0.0)))


@numba.njit(cache=True)
def _prepare(u_nominal, G, b, lower, upper):
    """The nominal clipped to the box [``lower``, ``upper``]; whether ``G``, ``b`` and
    ``u_nominal`` are finite; whether the clipped nominal then meets every row (it minimizes
    the cost over the box, so it is the QP's optimum and no solver call is needed); and,
    when a solver is needed, the rows kept (``kept_rows``), their padded count and the
    program's data (``load_qp``)."""
    clipped = np.minimum(np.maximum(u_nominal, lower), upper)
    finite, optimal = check_nominal(G, b, u_nominal, clipped)
    kept = np.empty(len(b), np.int64)
    count = kept_rows(G, b, lower, upper, kept) if finite and not optimal else 0
    size = padded_rows(count)
    data = np.empty(qp_data_size(len(u_nominal), size))
    load_qp(u_nominal, G, b, kept[:count], lower, upper, size, data)
    return clipped, finite, optimal, kept[:count], size, data


@compiled_helper
def kept_rows(G, b, lower, upper, kept):
    """How many rows of ``G`` u >= ``b`` some u in the box [``lower``, ``upper``] breaks
    (the others cannot change the optimum); their indices go to the start of ``kept``."""
    count = 0
    least = np.empty(G.shape[1])  # each term's minimum over the box
    for row in range(len(b)):
        for c in range(G.shape[1]):
            least[c] = G[row, c] * (lower[c] if G[row, c] > 0.0 else upper[c])
        if _pairwise_sum(least) < b[row]:
            kept[count] = row
            count += 1
    return count


@compiled_helper
def padded_rows(count):
    """``count`` rows padded to a multiple of ``_PAD`` (few program sizes)."""
    return -(-count // _PAD) * _PAD


@compiled_helper
def qp_data_size(columns, size):
    """The length of ``load_qp``'s block for ``columns`` = 2k inputs and ``size`` rows."""
    return 3 * columns + size + size * (columns + size)


@compiled_helper
def _pairwise_sum(a):
    """The sum of ``a`` exactly as numpy's ``sum`` adds it, so that decisions match numpy's
    to the bit: blocks of at most 128 with eight accumulators; a longer range is split in
    two (the first part a multiple of 8 long) and the parts' sums added."""
    if len(a) <= 128:  # one block (every QP of up to 64 robots): no task stack to allocate
        return _block_sum(a, np.int64(0), len(a))  # int64, not Literal[int](0): one copy
    tasks = np.empty((128, 3), np.int64)  # start, length, halves already queued
    sums = np.empty(128)
    tasks[0, 0], tasks[0, 1], tasks[0, 2] = 0, len(a), 0
    top, done = 1, 0
    while top > 0:
        top -= 1
        start, n, queued = tasks[top, 0], tasks[top, 1], tasks[top, 2]
        if n <= 128:
            sums[done] = _block_sum(a, start, n)
            done += 1
        elif queued:
            done -= 1
            sums[done - 1] += sums[done]
        else:
            half = n // 2 - (n // 2) % 8
            tasks[top, 2] = 1
            tasks[top + 1, 0], tasks[top + 1, 1], tasks[top + 1, 2] = start + half, n - half, 0
            tasks[top + 2, 0], tasks[top + 2, 1], tasks[top + 2, 2] = start, half, 0
            top += 3
    return sums[0]


@compiled_helper
def _block_sum(a, start, n):
    if n < 8:
        total = -0.0
        for i in range(start, start + n):
            total += a[i]
        return total
    r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
    r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
    i = 8
    while i < n - n % 8:
        j = start + i
        r0, r1, r2, r3 = r0 + a[j], r1 + a[j + 1], r2 + a[j + 2], r3 + a[j + 3]
        r4, r5, r6, r7 = r4 + a[j + 4], r5 + a[j + 5], r6 + a[j + 6], r7 + a[j + 7]
        i += 8
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        total += a[start + i]
        i += 1
    return total


@compiled_helper
def load_qp(u_nominal, G, b, kept, lower, upper, size, out):
    """A ``LoadedQp``'s ``data`` in ``out`` (``qp_data_size`` long) for rows ``G`` u >=
    ``b`` of which those ``kept`` are the first rows of A (the rest, up to ``size``, read
    0 >= -1), the linear cost of ``u_nominal`` and the box [``lower``, ``upper``]."""
    columns = len(u_nominal)
    for c in range(columns):
        out[c] = u_nominal[c] * -2.0
        out[columns + c] = lower[c]
        out[2 * columns + c] = upper[c]
    rows_lower = 3 * columns
    A = out[rows_lower + size:].reshape((size, columns + size))
    for row in range(size):
        keep = row < len(kept)
        for c in range(columns):
            A[row, c] = G[kept[row], c] if keep else 0.0
        for c in range(size):
            A[row, columns + c] = 1.0 if c == row else 0.0
        out[rows_lower + row] = b[kept[row]] if keep else -1.0


@compiled_helper
def check_nominal(G, b, u_nominal, clipped) -> tuple[bool, bool]:
    """Whether ``G``, ``b`` and ``u_nominal`` are all finite, and whether then ``clipped``
    (the nominal clipped to the input bounds) meets every row ``G u >= b``: it is then the
    QP's optimum, compiled."""
    finite = True  # element by element: np.all(np.isfinite(...)) compiles numba's generic code
    for row in range(len(b)):
        finite = finite and math.isfinite(b[row])
        for column in range(G.shape[1]):
            finite = finite and math.isfinite(G[row, column])
    for column in range(len(u_nominal)):
        finite = finite and math.isfinite(u_nominal[column])
    if not finite:
        return False, False
    for row in range(len(b)):
        value = 0.0
        for column in range(len(clipped)):
            value += G[row, column] * clipped[column]
        if not value >= b[row]:
            return True, False
    return True, True
