"""A compiled QP solver for the CBF QP's hard part: the dual active-set method of Goldfarb and
Idnani (Math. Programming 27, 1983), as QuadProg++ implements it, specialised to the
projection the CBF QP is when its rows can all be met::

    min |u - u_nom|^2  s.t.  A u >= c,  lo <= u <= hi

(u: 2k inputs, m/s^2 and rad/s; rows scaled as in ``safety_rows``). Starting from the
unconstrained optimum u_nom it adds the most violated constraint, dropping active ones whose
multipliers would turn negative, until every constraint holds: a finite number of steps,
each a few Givens rotations on (2k x 2k) matrices, microseconds for the controller's QPs
against ~100 us for Clarabel. It answers "infeasible" when no u meets every row; the slack
of ``qp_solver``'s QP is then needed and ``CbfQp`` solves that QP with Clarabel.

Its answer is the QP's exact optimum up to rounding (Clarabel's interior point stops within
its tolerances), so trajectories differ from Clarabel's in the last bits and beyond.
"""

import math

import numba
import numpy as np

from mrta_drake.stack.compiled_helper import compiled_helper

_EPS = 2.220446049250313e-16  # float64 machine epsilon
_MAX_STEPS = 1000  # more: answer infeasible (Clarabel then solves the QP)


# What ``solve_qps`` found of each QP (``status``).
NOT_LOADED = 0  # no block: not solved
SOLVED = 1  # every row met, no multiplier outweighs the slack: u holds its answer
HEAVY = 2  # every row met, but a multiplier outweighs the slack weight: needs the slack QP
UNMET = 3  # no u within the bounds meets every row: needs the slack QP


@numba.njit(cache=True)
def solve_qps(data, data_start, kept_count, sizes, members, group_start, slack_weight, u,
              status):
    """Every QP whose block (``qp_solver.load_qp``) is ``data[data_start[g]:data_start[g +
    1]]`` (QPs with an empty block are ``NOT_LOADED``), over the robots ``members[
    group_start[g]:group_start[g + 1]]``, with ``kept_count[g]`` real rows padded to
    ``sizes[g]``, in one call: ``dual_active_set`` on each, and where it is ``SOLVED``
    (the slack-free optimum is the QP's while no multiplier reaches ``slack_weight``) its
    answer clipped to the bounds (as ``np.minimum(np.maximum(x, lo), hi)``) goes to the
    members' rows of ``u`` (N, 2) ``[a, omega]``; ``status[g]`` says what was found."""
    for g in range(len(data_start) - 1):
        if data_start[g + 1] == data_start[g]:
            status[g] = NOT_LOADED
            continue
        n = 2 * (group_start[g + 1] - group_start[g])
        block = data[data_start[g]:data_start[g + 1]]
        x, met, largest = dual_active_set(block, n, sizes[g], kept_count[g])
        if not met:
            status[g] = UNMET
        elif not largest < slack_weight:
            status[g] = HEAVY
        else:
            status[g] = SOLVED
            for j in range(n):
                u[members[group_start[g] + j // 2], j % 2] = _numpy_clip(x[j], block[n + j],
                                                                   block[2 * n + j])


@compiled_helper
def _numpy_clip(x, lo, hi):
    """``np.minimum(np.maximum(x, lo), hi)`` for numbers to the bit: a NaN propagates, and
    of two equal numbers (0.0 and -0.0) numpy returns the second."""
    if x != x or lo != lo:
        return x if x != x else lo
    low = x if x > lo else lo
    if hi != hi:
        return hi
    return low if low < hi else hi


@compiled_helper
def dual_active_set(data, columns, size, kept):
    """The QP loaded in ``data`` (``qp_solver.load_qp``'s block for ``columns`` = 2k inputs
    and ``size`` padded rows, the first ``kept`` of them real) without slack: the optimum u
    (2k,), whether every row and bound could be met (else u is meaningless) and the largest
    multiplier of an active constraint (the slack weight it takes for the slack-free optimum
    to be the QP's too)."""
    n = columns
    m = kept + 2 * n  # rows, then u >= lo, then -u >= -hi
    rows = data[3 * n + size:].reshape((size, n + size))
    normals, offsets = np.empty((m, n)), np.empty(m)  # constraint i: normals[i] u >= offsets[i]
    for i in range(m):
        for j in range(n):
            normals[i, j] = 0.0
    for i in range(kept):
        for j in range(n):
            normals[i, j] = rows[i, j]
        offsets[i] = data[3 * n + i]
    for j in range(n):
        normals[kept + j, j], offsets[kept + j] = 1.0, data[n + j]
        normals[kept + n + j, j], offsets[kept + n + j] = -1.0, -data[2 * n + j]
    x = np.empty(n)
    for j in range(n):
        x[j] = data[j] * -0.5  # the linear cost is -2 u_nom
    # Hessian 2I = L L^T with L = sqrt(2) I, so J = L^-T = I / sqrt(2) to start with.
    J, R = np.zeros((n, n)), np.zeros((n, n))
    for j in range(n):
        J[j, j] = 1.0 / math.sqrt(2.0)
    active, dual = np.zeros(n + 1, np.int64), np.zeros(n + 1)
    is_active = np.zeros(m, np.bool_)
    s, d, z, r, normal = np.empty(m), np.empty(n), np.empty(n), np.empty(n + 1), np.empty(n)
    # int64 from the start: a literal 0 (or -1) would compile each helper it reaches twice,
    # for Literal[int](0) while numba's typing widens it and for int64 (~0.8 CPU s cold).
    q, r_norm = np.int64(0), 1.0
    tolerance = m * _EPS * (2.0 * n) * (n / math.sqrt(2.0)) * 100.0
    steps = 0
    while steps < _MAX_STEPS:
        violation, p, worst = 0.0, -1, 0.0  # p: the most violated constraint
        for i in range(m):
            s[i] = _dot(normals[i], x) - offsets[i]
            violation += min(0.0, s[i])
            if s[i] < worst and not is_active[i]:
                p, worst = i, s[i]
        if abs(violation) <= tolerance or p < 0:
            return x, True, _largest(dual, active, q, kept)
        for j in range(n):
            normal[j] = normals[p, j]
        dual[q], active[q] = 0.0, p  # p joins with multiplier dual[q]
        while steps < _MAX_STEPS:
            steps += 1
            _directions(J, R, normal, q, d, z, r)
            blocking, partial = np.int64(-1), math.inf  # largest dual step keeping multipliers >= 0
            for k in range(q):
                if r[k] > 0.0 and dual[k] / r[k] < partial:
                    partial, blocking = dual[k] / r[k], active[k]
            full = math.inf  # the primal step that makes p active
            if _dot(z, z) > _EPS:
                full = -s[p] / _dot(z, normal)
                if full < 0.0:
                    full = math.inf
            step = min(partial, full)
            if step == math.inf:
                return x, False, 0.0  # no u meets every constraint
            for k in range(q):
                dual[k] -= step * r[k]
            dual[q] += step
            if full < math.inf:
                for j in range(n):
                    x[j] += step * z[j]
                if abs(step - full) < _EPS:  # p is met: it becomes active
                    added, r_norm = _add_active(R, J, d, q, r_norm)
                    if not added:
                        return x, False, 0.0  # p depends on the active ones (degenerate)
                    is_active[p] = True
                    q += 1
                    break
            is_active[blocking] = False  # its multiplier reached zero: drop it
            q = _drop(R, J, active, dual, n, q, blocking)
            s[p] = _dot(normals[p], x) - offsets[p]
    return x, False, 0.0


@compiled_helper
def _dot(a, b):
    total = 0.0
    for j in range(len(a)):
        total += a[j] * b[j]
    return total


@compiled_helper
def _largest(dual, active, q, rows):
    """The largest multiplier of the q active constraints that are rows (index < ``rows``)."""
    largest = 0.0
    for k in range(q):
        if active[k] < rows:
            largest = max(largest, dual[k])
    return largest


@compiled_helper
def _directions(J, R, normal, q, d, z, r):
    """For the constraint ``normal``: d = J^T normal, the primal step direction z (the part
    of J beyond the q active constraints) and the change r = R^-1 d of the q multipliers."""
    n = len(d)
    for i in range(n):
        total = 0.0
        for j in range(n):
            total += J[j, i] * normal[j]
        d[i] = total
    for i in range(n):
        total = 0.0
        for j in range(q, n):
            total += J[i, j] * d[j]
        z[i] = total
    for i in range(q - 1, -1, -1):
        total = 0.0
        for j in range(i + 1, q):
            total += R[i, j] * r[j]
        r[i] = (d[i] - total) / R[i, i]


@compiled_helper
def _rotate(a, b):
    """A Givens rotation (cos, sin, norm) taking (a, b) to (norm, 0), with cos >= 0."""
    h = math.hypot(a, b)
    c, s = a / h, b / h
    if c < 0.0:
        return -c, -s, -h
    return c, s, h


@compiled_helper
def _add_active(R, J, d, q, r_norm):
    """Adds the constraint with d = J^T normal as the (q + 1)-th active one: rotates d's tail
    into its q-th entry (updating J) and appends d's head to R. Returns whether it is
    independent of the active ones, and the new scale of R."""
    n = len(d)
    for j in range(n - 1, q, -1):
        if d[j - 1] == 0.0 and d[j] == 0.0:
            continue
        c, s, h = _rotate(d[j - 1], d[j])
        d[j - 1], d[j] = h, 0.0
        ratio = s / (1.0 + c)
        for k in range(n):
            a, b = J[k, j - 1], J[k, j]
            J[k, j - 1] = a * c + b * s
            J[k, j] = ratio * (a + J[k, j - 1]) - b
    for i in range(q + 1):
        R[i, q] = d[i]
    if abs(d[q]) <= _EPS * r_norm:
        return False, r_norm
    return True, max(r_norm, abs(d[q]))


@compiled_helper
def _drop(R, J, active, dual, n, q, constraint):
    """Removes ``constraint`` from the q active ones (with the multiplier of the one being
    added, at index q, moving down), restoring R's triangle by Givens rotations. Returns
    the new count."""
    at = 0
    while active[at] != constraint:
        at += 1
    for i in range(at, q - 1):
        active[i], dual[i] = active[i + 1], dual[i + 1]
        for j in range(n):
            R[j, i] = R[j, i + 1]
    active[q - 1], dual[q - 1] = active[q], dual[q]
    active[q], dual[q] = 0, 0.0
    for j in range(q):
        R[j, q - 1] = 0.0
    q -= 1
    for j in range(at, q):
        if R[j, j] == 0.0 and R[j + 1, j] == 0.0:
            continue
        c, s, h = _rotate(R[j, j], R[j + 1, j])
        R[j, j], R[j + 1, j] = h, 0.0
        ratio = s / (1.0 + c)
        for k in range(j + 1, q):
            a, b = R[j, k], R[j + 1, k]
            R[j, k] = a * c + b * s
            R[j + 1, k] = ratio * (a + R[j, k]) - b
        for k in range(n):
            a, b = J[k, j], J[k, j + 1]
            J[k, j] = a * c + b * s
            J[k, j + 1] = ratio * (J[k, j] + a) - b
    return q
