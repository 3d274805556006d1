"""Steering of blocked robots: a standing unicycle's yaw rate does not enter any barrier row
(``barriers``), so its QP has no reason to turn, and a robot nosing into a corner would wait
forever. This turns it along the obstacle that blocks it."""

import math

import numba
import numpy as np

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.nominal import wrap_angle
from mrta_drake.control.safety_rows import SafetyRows

# rad: a blocked robot heads this far past the blocking point's tangent, away from the point.
# At the tangent itself the push's coefficient in the point's row is zero, its sign left to
# rounding: a robot at its wall distance turned onto the tangent and stood there, the row
# barring any push at -0.002 (issue 15). Driving on at 0.3 rad (17 degrees) past the
# tangent it leaves the point; along a straight wall the points ahead bar it less than at
# the tangent.
PAST_TANGENT = 0.3


def steer_blocked(u_nominal, states, rows: SafetyRows, lower, upper,
                  params: CbfParams) -> np.ndarray:
    """The nominal inputs (k, 2) of a QP's robots ``states`` (k, 4), with a new yaw rate for
    every robot that stands (|v| < ``coordination.stall_speed``) and whose nominal push
    forward breaks a safety row: it turns towards the tangent of the most blocking obstacle
    point nearer its goal heading, ``PAST_TANGENT`` beyond it (away from the point). The
    rows are judged at the nominal clipped to the hard bounds ``lower``, ``upper`` (k, 2),
    the inputs the robots can be commanded."""
    u = np.array(u_nominal, dtype=float).reshape(-1, 2)
    steer(u, np.ascontiguousarray(states, dtype=float).reshape(-1, 4),
          *(np.ascontiguousarray(a) for a in (rows.G, rows.b, rows.member, rows.other,
                                              rows.normal)),
          params.coordination.stall_speed, params.nominal.k_theta,
          *(np.ascontiguousarray(a, dtype=float).reshape(-1, 2) for a in (lower, upper)))
    return u


@numba.njit(cache=True)
def steer(u, states, G, b, member, other, normal, stall_speed, k_theta, lower, upper):
    """``steer_blocked`` in place on ``u`` (k, 2), compiled: rows ``G``, ``b``, ``member``,
    ``other``, ``normal`` as in ``SafetyRows``, bounds ``lower``, ``upper`` (k, 2).

    The most blocking row is the most violated at the clipped nominal: at the unclipped one
    (a nominal acceleration of 2-4 m/s^2 against a limit of 1) a row whose violation grows
    faster with the push (a person straight ahead) won over the one the robot breaks most
    at what it can do (a wall at its side), and as each turn made the other row the most
    violated, a robot at a corridor's corner with a person ahead turned between the two
    tangents tick after tick (issue 15)."""
    violation = np.empty(len(b))
    for row in range(len(b)):
        value = 0.0
        for column in range(G.shape[1]):
            j, c = column // 2, column % 2
            value += G[row, column] * min(max(u[j, c], lower[j, c]), upper[j, c])
        violation[row] = value - b[row]
    for j in range(len(u)):
        if not (abs(states[j, 3]) < stall_speed and u[j, 0] > 0.0):
            continue
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
        turn = 0.5 * math.pi + PAST_TANGENT
        best = obstacle + turn
        if abs(wrap_angle(obstacle - turn - desired)) < abs(wrap_angle(best - desired)):
            best = obstacle - turn
        u[j, 1] = k_theta * wrap_angle(best - states[j, 2])
