"""Safety rows: the scaled CBF rows ``G u >= b`` of one QP (see ``barriers``), one per
obstacle point of each of its robots. Each row is divided by ``|r|`` (m) so that rows near and
far are equally scaled for the solver."""

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
        params.row_params, params.coordination.cluster_radius**2))


@numba.njit(cache=True)
def _rows_entry(states, hits, mask, humans, human_velocities, movers, params, radius2):
    """``safety_rows``' arrays (``count_rows``, ``empty_rows``, ``fill_rows``) for Python,
    which cannot call a ``compiled_helper``."""
    rows = empty_rows(count_rows(states, mask, len(humans), movers, radius2), len(states))
    G, b, kind, h, member, other, normal = rows
    fill_rows(states, hits, mask, humans, human_velocities, movers, params, G, b, kind, h,
              member, other, normal)
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
def count_rows(states, mask, humans, movers, radius2):
    """The number of rows ``safety_rows`` makes (``humans``: how many)."""
    k = len(states)
    m = k * humans
    for i in range(k):
        for ray in range(mask.shape[1]):  # not mask.sum(): numba compiles its generic code
            m += mask[i, ray]
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
def fill_rows(states, hits, mask, humans, human_velocities, movers, params, G, b, kind, h,
              member, other, normal):
    """Fills ``safety_rows``' arrays (``params``: ``CbfParams.row_params``; ``G`` zero).
    Rows in order: walls, humans, movers (each robot by robot), pairs. The wall point in
    column ``params[11]`` (the closest point) takes the distance ``params[10]``."""
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
