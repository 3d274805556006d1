"""Steering of blocked robots: a standing unicycle's yaw rate does not enter any barrier row
(``barriers``), so its QP has no reason to turn, and a robot nosing into a corner would wait
forever. This turns it along the obstacle that blocks it."""

import math

import numba
import numpy as np

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.nominal import wrap_angle
from mrta_drake.control.safety_rows import SafetyRows
from mrta_drake.stack.compiled_helper import compiled_helper


def steer_blocked(u_nominal, states, rows: SafetyRows, params: CbfParams) -> np.ndarray:
    """The nominal inputs (k, 2) of a QP's robots ``states`` (k, 4), with a new yaw rate for
    every robot that stands (|v| < ``coordination.stall_speed``) and whose nominal push
    forward breaks a safety row: it turns towards the tangent of the most blocking obstacle
    point nearer its goal heading. A push forward asks for more than standing: the speed
    its acceleration a aims at, v + a / ``nominal.k_v``, is above the stall speed. A
    standing robot turning in place (heading gate) or slowing down has a = -k v (k = k_v,
    k_slow), which is positive or negative by rounding at v ~ 0: steered on it, the robot
    turned to the tangent instead of its goal heading, and then, the goal outside its
    heading gate, stood there for good (docs/control.md, "QP solvers")."""
    u = np.array(u_nominal, dtype=float).reshape(-1, 2)
    _steer_entry(u, np.ascontiguousarray(states, dtype=float).reshape(-1, 4),
                 *(np.ascontiguousarray(a) for a in (rows.G, rows.b, rows.member, rows.other,
                                                     rows.normal)),
                 params.coordination.stall_speed, params.nominal.k_v, params.nominal.k_theta)
    return u


@numba.njit(cache=True)
def _steer_entry(u, states, G, b, member, other, normal, stall_speed, k_v, k_theta):
    """``steer`` for Python, which cannot call a ``compiled_helper``."""
    steer(u, states, G, b, member, other, normal, stall_speed, k_v, k_theta)


@compiled_helper
def steer(u, states, G, b, member, other, normal, stall_speed, k_v, k_theta):
    """``steer_blocked`` in place on ``u`` (k, 2), compiled: rows ``G``, ``b``, ``member``,
    ``other``, ``normal`` as in ``SafetyRows``."""
    violation = np.empty(len(b))
    measured = False  # the rows' violations by the nominal as it came in, once needed
    for j in range(len(u)):
        if not (abs(states[j, 3]) < stall_speed and states[j, 3] + u[j, 0] / k_v > stall_speed):
            continue
        if not measured:  # no input has changed yet: u is the nominal as it came in
            measured = True
            for row in range(len(b)):
                value = 0.0
                for column in range(G.shape[1]):
                    value += G[row, column] * u[column // 2, column % 2]
                violation[row] = value - b[row]
        row, worst = -1, math.inf
        for r in range(len(b)):
            if ((member[r] == j or other[r] == j) and G[r, 2 * j] < 0.0
                    and violation[r] < 0.0 and violation[r] < worst):
                row, worst = r, violation[r]
        if row < 0:
            continue
        # The unit vector away from the obstacle point (normal points away from member's).
        sign = 1.0 if member[row] == j else -1.0
        obstacle = math.atan2(-(sign * normal[row, 1]), -(sign * normal[row, 0]))
        desired = states[j, 2] + u[j, 1] / k_theta
        best = obstacle + 0.5 * math.pi
        if abs(wrap_angle(obstacle - 0.5 * math.pi - desired)) < abs(wrap_angle(best - desired)):
            best = obstacle - 0.5 * math.pi
        u[j, 1] = k_theta * wrap_angle(best - states[j, 2])
