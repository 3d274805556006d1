"""Second-order control barrier functions for dynamic unicycles.

Model (world frame, m, rad, s). Robot state ``[x, y, theta, v]``, input ``u = [a, omega]``::

    p_dot = v e,   v_dot = a,   theta_dot = omega,   e = [cos theta, sin theta],
    p_ddot = a e + v omega n,   n = [-sin theta, cos theta]   (since e_dot = omega n).

Barrier for a robot at ``p`` and an obstacle point ``o`` (a wall ray hit, a human or another
robot) with safety distance ``d``; ``r = p - o``::

    h      = r.r - d^2
    h_dot  = 2 r.r_dot
    h_ddot = 2 r_dot.r_dot + 2 r.r_ddot

- wall point (static): ``r_dot = v e``, ``r_ddot = a e + v omega n``;
- human (constant-velocity prediction ``w``): ``r_dot = v e - w``, ``r_ddot = a e + v omega n``;
- robot pair ``(i, j)``, ``r = p_i - p_j``: ``r_dot = v_i e_i - v_j e_j``,
  ``r_ddot = a_i e_i + v_i omega_i n_i - a_j e_j - v_j omega_j n_j``.

So ``h_ddot = 2 |r_dot|^2 + 2 (r.e) a + 2 v (r.n) omega [- 2 (r.e_j) a_j - 2 v_j (r.n_j) omega_j]``
is affine in the inputs; ``omega`` acts only through ``v omega`` (a standing robot cannot turn
away from an obstacle, it can only brake or accelerate). The exponential CBF condition
``h_ddot + (a1 + a2) h_dot + a1 a2 h >= 0`` is then one linear row ``g.u >= b`` per obstacle
point, with ``b = -(2 |r_dot|^2 + (a1 + a2) h_dot + a1 a2 h)`` (``safety_rows``).
"""

from dataclasses import dataclass

import numba
import numpy as np

from mrta_drake.errors import require_non_negative, require_positive
from mrta_drake.stack.compiled_helper import compiled_helper


@dataclass(frozen=True)
class SafetyDistances:
    """Safety distance ``d`` (m) from a robot's centre to a wall ray hit, a human's centre and
    another robot's centre.

    ``wall_contact`` (m, robot centre to wall) is the distance kept from the closest obstacle
    point where no wall ray sees it (``SensingParams.closest_point_range``): a contact
    guard, the demo robots' 0.22 m radius plus 0.08 m, not the rays' ``wall`` distance, so
    that a robot on a path running nearer a wall than ``wall`` (derived lanes keep 0.47 m, a
    path cutting a corner) goes on, while a thin wall end between two rays is kept off the
    robot's body. Used as at most ``wall`` (``CbfParams.row_params``), by ``cluster_cbf``'s
    safety rows only."""

    wall: float = 0.6
    human: float = 0.6
    robot: float = 0.6
    wall_contact: float = 0.3

    def __post_init__(self):
        require_non_negative(self, "wall", "human", "robot", "wall_contact")


@dataclass(frozen=True)
class BarrierRates:
    """The CBF rates ``alpha1``, ``alpha2`` (1/s) per obstacle kind (defaults from the
    paper)."""

    alpha1_wall: float = 2.0
    alpha2_wall: float = 6.0
    alpha1_human: float = 1.0
    alpha2_human: float = 2.0
    alpha1_robot: float = 2.0
    alpha2_robot: float = 5.0

    def __post_init__(self):
        require_positive(self, "alpha1_wall", "alpha2_wall", "alpha1_human", "alpha2_human",
                         "alpha1_robot", "alpha2_robot")


@dataclass(frozen=True)
class BarrierTerms:
    """Barrier values and derivatives for a batch of (robot, obstacle point) pairs.

    All arrays have shape (m,) except the input coefficients, (m, 2) over ``[a, omega]``:
    ``h_ddot = drift + own . u_own + other . u_other`` (``other`` is zero unless the obstacle
    is a robot whose input is a decision variable too). Units: h m^2, h_dot m^2/s,
    h_ddot m^2/s^2.
    """

    h: np.ndarray
    h_dot: np.ndarray
    drift: np.ndarray
    own: np.ndarray
    other: np.ndarray
    offset: np.ndarray  # r = p - o (m, 2), m
    distance: np.ndarray  # |r|, m


def point_barrier(position, heading, speed, points, point_velocities, safety_distance):
    """Barrier terms of robots (``position`` (m, 2) or (2,), ``heading``, ``speed``) against
    obstacle points (m, 2) moving at constant ``point_velocities`` (m, 2), world frame."""
    o = np.asarray(points, dtype=float)
    p, w = (np.broadcast_to(np.asarray(a, dtype=float), o.shape)
            for a in (position, point_velocities))
    heading, v = (np.broadcast_to(np.asarray(a, dtype=float), o.shape[:-1])
                  for a in (heading, speed))
    h, h_dot, drift, own_a, own_w, rx, ry, distance = _point_terms_entry(
        *(np.ascontiguousarray(a) for a in (p[..., 0], p[..., 1], heading, v, o[..., 0],
                                            o[..., 1], w[..., 0], w[..., 1])),
        float(safety_distance))
    own = np.stack([own_a, own_w], axis=-1)
    return BarrierTerms(h, h_dot, drift, own, np.zeros_like(own), np.stack([rx, ry], axis=-1),
                        distance)


def cbf_rhs(terms: BarrierTerms, alpha1: float, alpha2: float) -> np.ndarray:
    """``b`` of the unscaled rows ``own.u + other.u_j >= b``."""
    return _rhs_entry(terms.drift, terms.h_dot, terms.h, float(alpha1), float(alpha2))


# The formulas above, compiled; each works on scalars (in the row kernel) and on arrays.


@numba.njit(cache=True)
def _point_terms_entry(px, py, heading, v, ox, oy, wx, wy, safety_distance):
    """``point_terms`` for Python, which cannot call a ``compiled_helper``."""
    return point_terms(px, py, heading, v, ox, oy, wx, wy, safety_distance)


@numba.njit(cache=True)
def _rhs_entry(drift, h_dot, h, alpha1, alpha2):
    """``rhs`` for Python, which cannot call a ``compiled_helper``."""
    return rhs(drift, h_dot, h, alpha1, alpha2)


@compiled_helper
def point_terms(px, py, heading, v, ox, oy, wx, wy, safety_distance):
    """h, h_dot, drift, the coefficients of [a, omega], r = p - o and |r| of a robot at
    (px, py) with ``heading`` and speed ``v`` against a point (ox, oy) moving at (wx, wy)
    (see the module docstring)."""
    c, s = np.cos(heading), np.sin(heading)
    rx, ry = px - ox, py - oy
    vx, vy = v * c - wx, v * s - wy
    r2 = rx * rx + ry * ry
    return (r2 - safety_distance * safety_distance, 2.0 * (rx * vx + ry * vy),
            2.0 * (vx * vx + vy * vy), 2.0 * (rx * c + ry * s), 2.0 * v * (ry * c - rx * s),
            rx, ry, np.sqrt(r2))


@compiled_helper
def pair_other(rx, ry, heading_j, v_j):
    """The coefficients of robot j's [a, omega] in a pair row, r = p_i - p_j."""
    c, s = np.cos(heading_j), np.sin(heading_j)
    return -2.0 * (rx * c + ry * s), -2.0 * v_j * (ry * c - rx * s)


@compiled_helper
def rhs(drift, h_dot, h, alpha1, alpha2):
    """``b`` of the CBF condition with rates ``alpha1``, ``alpha2`` (1/s)."""
    return -(drift + (alpha1 + alpha2) * h_dot + alpha1 * alpha2 * h)
