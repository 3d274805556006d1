"""Safety rows: the scaled CBF rows ``G u >= b`` of one QP (see ``barriers``), one per
obstacle point of each of its robots. Each row is divided by ``|r|`` (m) so that rows near and
far are equally scaled for the solver."""

import math
from dataclasses import dataclass

import numba
import numpy as np

from mrta_drake.control.barriers import pair_other, point_terms, rhs
from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.stack.compiled_helper import compiled_helper

WALL, HUMAN, ROBOT = 0, 1, 2  # row kinds
_MIN_SCALE = 1e-3  # m; rows for points closer than this are scaled as if at this distance


@dataclass(frozen=True)
class SafetyRows:
    """Scaled CBF rows ``G u >= b`` of one QP over k robots (u (2k,) stacked ``[a, omega]``).
    Per row: ``kind`` (``WALL``, ``HUMAN``, ``ROBOT``), barrier value ``h`` (m^2), the robot
    it protects (``member``, index in the QP), the other robot of a pair row (``other``, -1
    for none) and the unit vector from the obstacle point to ``member`` (``normal`` (m, 2))."""

    G: np.ndarray
    b: np.ndarray
    kind: np.ndarray
    h: np.ndarray
    member: np.ndarray
    other: np.ndarray
    normal: np.ndarray


def safety_rows(states, hits, hit_mask, human_positions, human_velocities, movers,
                params: CbfParams) -> SafetyRows:
    """All safety rows of one QP whose inputs are those of the robots in ``states`` (k, 4):

    - each robot's wall rows at its own ``hits`` (k, R, 2) where ``hit_mask`` (k, R) (the
      closest point, after ``SensingParams.ray_count`` rays, at
      ``SafetyDistances.wall_contact``);
    - each robot's rows for every human (positions and velocities (M, 2));
    - each robot's rows for every robot in ``movers`` (q, 4) within the cluster radius
      (``CoordinationParams.cluster_radius``): robots outside the QP, predicted at constant
      velocity;
    - one row per pair of robots in the QP within the cluster radius, in both robots' inputs.
    """
    states = np.ascontiguousarray(states, dtype=float).reshape(-1, 4)
    k = len(states)
    hits = np.ascontiguousarray(hits, dtype=float).reshape(k, -1, 2)
    mask = np.ascontiguousarray(hit_mask, dtype=bool).reshape(k, -1)
    humans = np.ascontiguousarray(human_positions, dtype=float).reshape(-1, 2)
    movers = np.ascontiguousarray(movers, dtype=float).reshape(-1, 4)
    return SafetyRows(*_rows_entry(
        states, hits, mask, humans,
        np.ascontiguousarray(human_velocities, dtype=float).reshape(-1, 2), movers,
        params.row_params))


@numba.njit(cache=True)
def _rows_entry(states, hits, mask, humans, human_velocities, movers, params):
    """``safety_rows``' arrays (``count_rows``, ``empty_rows``, ``fill_rows``, every row: no
    input box to prove one idle against) for Python, which cannot call a
    ``compiled_helper``."""
    unbounded, near = np.full((len(states), 2), np.inf), np.zeros((len(states), len(humans)),
                                                                   np.bool_)
    rows = empty_rows(count_rows(states, mask, near, movers, params[9] * params[9]),
                      len(states))
    G, b, kind, h, member, other, normal = rows
    fill_rows(states, hits, mask, humans, human_velocities, near, movers, params, -unbounded,
              unbounded, G, b, kind, h, member, other, normal)
    return rows


@compiled_helper
def empty_rows(m, k):
    """Arrays for m rows over k robots: ``SafetyRows``' fields, ``G`` zero, ``other`` -1."""
    other = np.empty(m, np.int64)
    for row in range(m):  # not np.full: numba compiles its generic code for that
        other[row] = -1
    return (np.zeros((m, 2 * k)), np.empty(m), np.empty(m, np.int64), np.empty(m),
            np.empty(m, np.int64), other, np.empty((m, 2)))


@compiled_helper
def count_rows(states, mask, far, movers, radius2):
    """The number of rows ``safety_rows`` makes, less the humans' rows left out where
    ``far`` (k, M) (``far_humans``); ``fill_rows`` may make fewer."""
    k = len(states)
    m = 0
    for i in range(k):
        for ray in range(mask.shape[1]):  # not mask.sum(): numba compiles its generic code
            m += mask[i, ray]
        for q in range(far.shape[1]):
            m += not far[i, q]
        for q in range(len(movers)):
            m += _within_radius(states[i], movers[q], radius2)
        for j in range(i + 1, k):
            m += _within_radius(states[i], states[j], radius2)
    return m


@compiled_helper
def _within_radius(a, b, radius2):
    """Whether robot states ``a`` and ``b`` are at most sqrt(``radius2``) (m) apart."""
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 <= radius2


@compiled_helper
def fill_rows(states, hits, mask, humans, human_velocities, far, movers, params, lower,
              upper, G, b, kind, h, member, other, normal):
    """Fills ``safety_rows``' arrays (``params``: ``CbfParams.row_params``; ``G`` zero, at
    least ``count_rows`` rows) and returns how many rows it made. Rows in order: walls,
    humans, movers (each robot by robot), pairs. The wall point in column ``params[11]``
    (the closest point) takes the distance ``params[10]``. A wall or human row that every
    input of its robot in the box [``lower``, ``upper``] (k, 2) meets is left out
    (``_idle``), and so are the humans' rows where ``far`` (k, M) (``far_humans``, made
    before the rows); infinite bounds and no ``far`` keep every row. (The movers' rows are
    all kept: few, and they show what a robot cut off from messages is kept clear of.)"""
    k, rays, count = len(states), mask.shape[1], len(humans)
    radius2 = params[9] * params[9]
    closest = np.int64(params[11])
    row = np.int64(0)  # not a literal: see _NO_OTHER
    for what in (WALL, HUMAN, ROBOT):
        base = 3 * what  # safety distance, alpha1, alpha2 of this kind in params
        points = rays if what == WALL else count if what == HUMAN else len(movers)
        for i in range(k):
            x, y, theta, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
            for q in range(points):
                if what == WALL:
                    if not mask[i, q]:
                        continue
                    terms = point_terms(x, y, theta, v, hits[i, q, 0], hits[i, q, 1], 0.0, 0.0,
                                        params[10] if q == closest else params[base])
                elif what == HUMAN:
                    if far[i, q]:
                        continue
                    terms = point_terms(x, y, theta, v, humans[q, 0], humans[q, 1],
                                        human_velocities[q, 0], human_velocities[q, 1],
                                        params[base])
                else:
                    if not _within_radius(states[i], movers[q], radius2):
                        continue
                    speed, heading = movers[q, 3], movers[q, 2]
                    terms = point_terms(x, y, theta, v, movers[q, 0], movers[q, 1],
                                        speed * np.cos(heading), speed * np.sin(heading),
                                        params[base])
                _put_row(row, terms, i, _NO_OTHER, 0.0, 0.0, what, params[base + 1],
                         params[base + 2], G, b, kind, h, member, other, normal)
                if what != ROBOT and _idle(G[row, 2 * i], G[row, 2 * i + 1], b[row],
                                           lower[i], upper[i]):
                    G[row, 2 * i] = G[row, 2 * i + 1] = 0.0  # left out: the next row's place
                else:
                    row += 1
    for i in range(k):
        for j in range(i + 1, k):
            if not _within_radius(states[i], states[j], radius2):
                continue
            speed, heading = states[j, 3], states[j, 2]
            terms = point_terms(states[i, 0], states[i, 1], states[i, 2], states[i, 3],
                                 states[j, 0], states[j, 1], speed * np.cos(heading),
                                 speed * np.sin(heading), params[6])
            other_a, other_w = pair_other(terms[5], terms[6], heading, speed)
            _put_row(row, terms, i, j, other_a, other_w, _PAIR, params[7], params[8], G, b,
                     kind, h, member, other, normal)
            row += 1
    return row


@compiled_helper
def far_humans(states, humans, velocities, lower, upper, params):
    """(k, M) whether the row of robot i (``states`` (k, 4)) for human q (``humans``,
    walking at ``velocities`` (M, 2) m/s) is ``_idle`` for the box [``lower[i]``,
    ``upper[i]``], decided from the distance alone, before the row is made (``params``:
    ``CbfParams.row_params``).

    With ``R = |r|`` and ``S = |v| + |w|`` (``barriers``: ``|r_dot| <= S``), ``|2 r.e| <=
    2 R`` and ``|2 v r.n| <= 2 |v| R`` bound the row's coefficients, so its least over the
    box is at least ``-2 R (A + |v| W)`` (``A``, ``W``: the largest |a|, |omega| in the
    box); and ``-b = 2 |r_dot|^2 + (a1 + a2) h_dot + a1 a2 h >= -2 (a1 + a2) R S + a1 a2
    (R^2 - d^2)``. When their sum is positive by more than 1e-9 of the terms' magnitudes
    (far above the rounding of the row's own arithmetic), the row as ``_idle`` computes it
    meets ``least >= b``: leaving it out here is leaving it out there."""
    d, alpha1, alpha2 = params[3], params[4], params[5]
    walking = np.empty(len(humans))
    for q in range(len(humans)):
        walking[q] = math.sqrt(velocities[q, 0] * velocities[q, 0]
                               + velocities[q, 1] * velocities[q, 1])
    far = np.empty((len(states), len(humans)), np.bool_)
    for i in range(len(states)):
        v = abs(states[i, 3])
        reach = 2.0 * (max(-lower[i, 0], upper[i, 0]) + v * max(-lower[i, 1], upper[i, 1]))
        for q in range(len(humans)):
            rx, ry = states[i, 0] - humans[q, 0], states[i, 1] - humans[q, 1]
            r2 = rx * rx + ry * ry
            distance, speed = math.sqrt(r2), v + walking[q]
            pull, approach = distance * reach, 2.0 * (alpha1 + alpha2) * distance * speed
            room = alpha1 * alpha2 * (r2 - d * d)
            scale = alpha1 * alpha2 * (r2 + d * d) + pull + approach + 2.0 * speed * speed
            far[i, q] = room - pull - approach > 1e-9 * scale
    return far


@compiled_helper
def _idle(g_a, g_omega, b, lower, upper):
    """Whether the row ``g_a a + g_omega omega >= b`` (one robot's columns) holds for every
    input ``[a, omega]`` in the box [``lower``, ``upper``] (2,), so that leaving it out
    changes nothing that reads the rows, when the box holds the robot's input bounds and its
    nominal input.

    Proof. The least of the row over the box is ``least = g_a l_a + g_omega l_omega`` with
    ``l`` the bound at which each term is smallest (the lower bound for a positive
    coefficient, else the upper). In floating point the products and the sum are rounded
    monotonically, so ``fl(least)`` <= ``fl(g_a a + g_omega omega)`` for every u in the box,
    and the row's other columns are zero (adding +-0 changes no sum): with ``fl(least) >=
    b``, (1) ``qp_solver.check_nominal`` finds the row met by the clipped nominal (inside
    the input bounds), (2) ``steering.steer`` finds its violation by the nominal >= 0 and so
    never steers on it, (3) ``qp_solver.kept_rows`` (the least over the input bounds, inside
    the box, summed with zeros between: the same two rounded terms, each no smaller) drops
    it, so the QP handed to a solver is the same rows in the same order, bit for bit, and a
    network follower's nominal or a standing robot's fixed turn (both clipped to the input
    bounds) meet it too. ``least`` and ``b`` must be finite (a non-finite row is kept, for
    ``check_nominal`` to fail its QP)."""
    least = (g_a * (lower[0] if g_a > 0.0 else upper[0])
             + g_omega * (lower[1] if g_omega > 0.0 else upper[1]))
    return math.isfinite(least) and math.isfinite(b) and least >= b


# numpy integers, not Python ones (so is ``fill_rows``' first ``row``): numba would compile
# ``_put_row`` once more for each literal integer argument.
_NO_OTHER, _PAIR = np.int64(-1), np.int64(ROBOT)


@compiled_helper
def _put_row(row, terms, i, j, other_a, other_w, what, alpha1, alpha2, G, b, kind, h, member,
             other, normal):
    """Row ``row`` for robot i (and robot j >= 0 of a pair), divided by |r| (at least
    ``_MIN_SCALE``) so that rows near and far are equally scaled."""
    value, h_dot, drift, own_a, own_w, rx, ry, distance = terms
    scale = 1.0 / max(distance, _MIN_SCALE)
    G[row, 2 * i], G[row, 2 * i + 1] = own_a * scale, own_w * scale
    if j >= 0:
        G[row, 2 * j], G[row, 2 * j + 1] = other_a * scale, other_w * scale
    b[row] = rhs(drift, h_dot, value, alpha1, alpha2) * scale
    kind[row], h[row], member[row], other[row] = what, value, i, j
    normal[row, 0], normal[row, 1] = rx * scale, ry * scale
