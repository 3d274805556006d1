"""Nominal (safety-unaware) control of a dynamic unicycle along a planned path.

As in the MRTA-Sim paper: the robot drives at the first path point at least ``lookahead`` away
(the local goal) with desired speed ``min(k_x dist, max_speed)``, acceleration
``k_v (v_des - v)`` and yaw rate ``k_theta * heading_error``; when the heading error exceeds
the heading gate (``heading_gate`` alone, ``heading_gate_cluster`` in a cluster) it turns in
place (``v_des = 0``). A robot with nothing to do, or a cluster member that is not the leader,
gets the slow-down nominal ``a = clip(-k_slow v, -slow_accel, slow_accel)``, ``omega = 0``.
With dense (grid-planner) paths the local goal is about ``lookahead`` ahead, so robots cruise at
``k_x lookahead`` = 0.75 m/s; ``max_speed`` caps the speed on sparse paths.

Beyond the paper:
- the local goal is searched on the path polyline (not only its vertices), from the robot's
  projection on; identical for dense paths, and sparse paths are followed without cutting
  corners;
- with ``stop_at_end`` the desired speed is capped by the braking profile
  ``sqrt(2 brake_accel s)`` (s: remaining path length) with its deceleration fed forward, and
  the robot brakes once within ``goal_tolerance`` of the end: it comes to rest on the end
  (within ~1 cm with the default robots) instead of overshooting and circling it;
- passing (``pass_offset`` > 0): when a body (another robot, a human) stands in the lane to
  the local goal (within ``pass_clearance`` of the line, closer than ``pass_range`` and before
  the path end), the robot heads for the point ``pass_offset`` to the right of the nearest such
  body. Two unicycles meeting head-on on one line would otherwise stop nose to nose: a standing
  unicycle cannot steer out of a position barrier.

Units: m, rad, s; world frame. Inputs are ``[a, omega]`` (m/s^2, rad/s).
"""

import math
from dataclasses import dataclass

import numpy as np

from mrta_drake.payloads import PATH_OK, RobotPath


@dataclass(frozen=True)
class NominalParams:
    """Gains and limits of nominal control (defaults as in the paper unless noted)."""

    k_x: float = 1.5  # 1/s, distance to desired speed
    k_v: float = 3.0  # 1/s, speed error to acceleration
    k_theta: float = 1.5  # 1/s, heading error to yaw rate
    lookahead: float = 0.5  # m, local goal = first path point at least this far away
    heading_gate: float = math.pi / 4  # rad, turn in place above this heading error (alone)
    heading_gate_cluster: float = math.pi / 2  # rad, the same for a robot in a cluster
    max_speed: float = 1.5  # m/s, nominal speed cap and hard command limit
    min_speed: float = -0.3  # m/s, hard lower command limit; reversing only ever for safety
    max_accel: float = 1.0  # m/s^2, hard |a| limit
    max_yaw_rate: float = 2.0  # rad/s, hard |omega| limit
    k_slow: float = 5.0  # 1/s, slow-down nominal gain
    slow_accel: float = 1.5  # m/s^2, slow-down nominal clip
    goal_tolerance: float = 0.05  # m, at rest within this of the end of a stop_at_end path
    brake_accel: float = 0.8  # m/s^2, braking profile to a path end (not in the paper)
    pass_offset: float = 0.7  # m, passing beside a body in the lane (not in the paper; 0: off)
    pass_clearance: float = 0.6  # m, half width of the lane checked for bodies
    pass_range: float = 4.0  # m, how far ahead bodies are checked


def slow_down(speed: float, params: NominalParams) -> np.ndarray:
    """The slow-down nominal ``[a, omega]``."""
    return np.array([np.clip(-params.k_slow * speed, -params.slow_accel, params.slow_accel), 0.0])


def wrap_angle(angle):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def local_goal(position, points: np.ndarray, lookahead: float) -> tuple[np.ndarray, bool, float]:
    """Where to drive along a path ``points`` (k, 2), k >= 1, from ``position``.

    The local goal is the first point of the path polyline at least ``lookahead`` from the
    robot, searching on from the robot's projection onto the nearest segment (for the dense
    paths a grid planner makes this is the paper's "first path point at least 0.5 m away"; for
    sparse paths it stays on the polyline instead of cutting corners). Without one it is the
    path end. Returns the goal, whether it is the path end, and the remaining path length from
    the projection to the end (m).
    """
    p = np.asarray(position, dtype=float)
    if len(points) == 1:
        return points[0], True, math.dist(p, points[0])
    start, seg = points[:-1], np.diff(points, axis=0)
    length2 = np.maximum(np.sum(seg * seg, axis=1), 1e-12)
    t = np.clip(np.sum((p - start) * seg, axis=1) / length2, 0.0, 1.0)
    nearest = int(np.argmin(np.sum((start + t[:, None] * seg - p) ** 2, axis=1)))
    lengths = np.sqrt(length2[nearest:])
    remaining = float((1.0 - t[nearest]) * lengths[0] + np.sum(lengths[1:]))
    projection = start[nearest] + t[nearest] * seg[nearest]
    if math.dist(p, projection) >= lookahead:  # off the path: head back to it
        return projection, remaining == 0.0, remaining
    # Per segment from the nearest on: the larger root s of |a + s d| = lookahead, a = start - p.
    a, d = start[nearest:] - p, seg[nearest:]
    b = np.sum(a * d, axis=1) / length2[nearest:]
    c = (np.sum(a * a, axis=1) - lookahead**2) / length2[nearest:]
    with np.errstate(invalid="ignore"):
        root = -b + np.sqrt(b * b - c)
    found = np.flatnonzero(root <= 1.0)  # NaN (never lookahead away) compares False
    if len(found) == 0:
        return points[-1], True, remaining
    i = int(found[0])
    return start[nearest + i] + root[i] * d[i], False, remaining


def passing_goal(position, goal, bodies, reach: float, params: NominalParams) -> np.ndarray:
    """``goal``, or, when a body (positions (n, 2)) stands in the lane from ``position`` towards
    ``goal`` no farther than ``reach`` (m), a point as far as ``goal`` in the direction of the
    point ``pass_offset`` to the right of the nearest such body."""
    if params.pass_offset <= 0.0 or len(bodies) == 0:
        return goal
    p = np.asarray(position, dtype=float)
    to_goal = goal - p
    dist = float(np.hypot(*to_goal))
    if dist < 1e-9:
        return goal
    ahead = to_goal / dist
    left = np.array([-ahead[1], ahead[0]])
    rel = np.asarray(bodies, dtype=float) - p
    along, lateral = rel @ ahead, rel @ left
    blocking = ((along > 0.0) & (along < min(params.pass_range, reach))
                & (np.abs(lateral) < params.pass_clearance))
    if not np.any(blocking):
        return goal
    nearest = int(np.argmin(np.where(blocking, along, np.inf)))
    aim = along[nearest] * ahead + (lateral[nearest] - params.pass_offset) * left
    # As far away as ``goal``, so that passing changes the heading but not the speed.
    return p + aim * (dist / np.hypot(*aim))


def track(state, goal, is_end: bool, remaining: float | None, heading_gate: float,
          params: NominalParams) -> np.ndarray:
    """Nominal ``[a, omega]`` driving robot ``state`` ``[x, y, theta, v]`` towards ``goal``.
    ``remaining``: path length (m) to where the robot must stop (None: no stop ahead);
    ``is_end``: ``goal`` is that stop."""
    x, y, theta, v = state
    dx, dy = goal[0] - x, goal[1] - y
    dist = math.hypot(dx, dy)
    if is_end and dist <= params.goal_tolerance:
        return slow_down(v, params)
    heading_error = float(wrap_angle(math.atan2(dy, dx) - theta))
    v_des, feedforward = min(params.k_x * dist, params.max_speed), 0.0
    if remaining is not None:
        # The braking profile to the stop; it governs the final approach, where k_x dist
        # would ask for more than max_accel. Its deceleration is fed forward so the speed
        # does not lag behind it.
        v_stop = math.sqrt(2.0 * params.brake_accel * max(remaining, dist if is_end else 0.0))
        if v_stop < v_des or is_end:
            v_des, feedforward = min(v_stop, params.max_speed), -params.brake_accel
    if abs(heading_error) > heading_gate:
        v_des, feedforward = 0.0, 0.0
    return np.array([params.k_v * (v_des - v) + feedforward, params.k_theta * heading_error])


def nominal_control(state, path: RobotPath | None, params: NominalParams, clustered: bool = False,
                    bodies=()) -> np.ndarray:
    """Nominal ``[a, omega]`` of a robot in ``state`` ``[x, y, theta, v]`` following ``path``
    (slow-down without an ``ok`` path). ``bodies`` (n, 2): positions of other robots and humans,
    used only for passing."""
    if path is None or path.status != PATH_OK or len(path.points) == 0:
        return slow_down(state[3], params)
    goal, is_end, remaining = local_goal(state[:2], path.points, params.lookahead)
    passing = passing_goal(state[:2], goal, bodies, remaining, params)
    if passing is not goal:
        goal, is_end = passing, False
    gate = params.heading_gate_cluster if clustered else params.heading_gate
    return track(state, goal, is_end, remaining if path.stop_at_end else None, gate, params)


def remaining_distance(state, path: RobotPath | None) -> float:
    """Straight-line distance (m) from the robot to its path end; inf without an ``ok`` path."""
    if path is None or path.status != PATH_OK or len(path.points) == 0:
        return math.inf
    return math.dist(state[:2], path.points[-1])


def is_active(state, path: RobotPath | None, arrival_radius: float) -> bool:
    """Whether the robot still has somewhere to go: an ``ok`` path, and unless the path lets
    it drive on, more than ``arrival_radius`` (m) from the path end."""
    if path is None or path.status != PATH_OK or len(path.points) == 0:
        return False
    return not (path.stop_at_end and remaining_distance(state, path) <= arrival_radius)
