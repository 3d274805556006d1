"""Nominal (safety-unaware) control of a dynamic unicycle along a planned path.

As in the MRTA-Sim paper: the robot drives at the first path point at least ``lookahead`` away
(the local goal) with desired speed ``min(k_x dist, max_speed)``, acceleration
``k_v (v_des - v)`` and yaw rate ``k_theta * heading_error``; when the heading error exceeds
the heading gate (``heading_gate`` alone, ``heading_gate_cluster`` in a cluster) it turns in
place (``v_des = 0``). A robot with nothing to do, or a cluster follower
(``mrta_drake.control.followers``), gets the slow-down nominal
``a = clip(-k_slow v, -slow_accel, slow_accel)``, ``omega = 0``.
With dense (grid-planner) paths the local goal is about ``lookahead`` ahead, so robots cruise at
``k_x lookahead`` = 0.75 m/s; ``max_speed`` caps the speed on sparse paths.

The paper also scales the desired speed by ``cos(heading error)``: ``heading_speed_factor``
(off by default; see docs/fidelity.md).

Beyond the paper:
- the local goal is searched on the path polyline (not only its vertices), from the robot's
  projection on; identical for dense paths, and sparse paths are followed without cutting
  corners;
- with ``stop_at_end`` the desired speed is capped by the braking profile
  ``sqrt(2 brake_accel s)`` (s: remaining path length) with its deceleration fed forward, and
  the robot brakes once within ``goal_tolerance`` of the end: it comes to rest on the end
  (within ~1 cm with the default robots) instead of overshooting and circling it
  (``braking_profile``; off, the desired speed is the paper's ``min(k_x dist, max_speed)``);
- passing (``pass_offset`` > 0): when a body (another robot, a human) stands in the lane to
  the local goal (within ``pass_clearance`` of the line, closer than ``pass_range`` and before
  the path end), the robot heads for the point ``pass_offset`` to the right of the nearest such
  body. Two unicycles meeting head-on on one line would otherwise stop nose to nose: a
  standing unicycle cannot steer out of a position barrier. But a body at rest (slower than
  ``ROBOT_STOPPED_SPEED``) more than ``pass_clearance / 2`` right of the lane is passed on
  its left, where there is more room: e.g. a robot waiting at a queue slot by the wall,
  beside a lane, is passed on the corridor side, not squeezed past along the wall. And a
  passing point with a wall nearer than ``pass_wall_room`` (the walls as the robot's wall
  rays see them, ``_wall_room``) is no way past: the body is passed on the other side if
  there is more room there. A robot standing at the wall distance beside a person in its
  lane would otherwise be sent into the wall, stopped by the barrier, for good.

Units: m, rad, s; world frame. Inputs are ``[a, omega]`` (m/s^2, rad/s).
"""

import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np

from mrta_drake.control.paths import has_path, segment_projection
from mrta_drake.errors import InputError, require_non_negative, require_positive
from mrta_drake.payloads import ROBOT_STOPPED_SPEED, RobotPath
from mrta_drake.stack.compiled_helper import compiled_helper


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
    pass_wall_room: float = 0.6  # m, a passing point this near a wall is no way past
    heading_speed_factor: bool = False  # desired speed x cos(heading error), as in the paper
    corner_steering: bool = True  # a standing robot blocked by a barrier turns along it
    braking_profile: bool = True  # cap the speed to stop at a path end (not in the paper)

    def __post_init__(self):
        require_positive(self, "k_x", "k_v", "k_theta", "lookahead", "heading_gate",
                         "heading_gate_cluster", "max_speed", "max_accel", "max_yaw_rate",
                         "slow_accel", "brake_accel")
        require_non_negative(self, "k_slow", "goal_tolerance", "pass_offset",
                             "pass_clearance", "pass_range", "pass_wall_room")
        if self.min_speed > 0:
            raise InputError(None, "min_speed", f"must be <= 0, got {self.min_speed!r}")

    @property
    def cruise_speed(self) -> float:
        """The speed robots drive along dense paths, m/s: ``min(k_x lookahead,
        max_speed)`` (module docstring)."""
        return min(self.k_x * self.lookahead, self.max_speed)

    @cached_property
    def gains(self) -> np.ndarray:
        """The fields as one array for compiled code (``nominal_inputs``,
        ``slow_down_input``)."""
        return np.array([self.k_x, self.k_v, self.k_theta, self.lookahead, self.heading_gate,
                         self.heading_gate_cluster, self.max_speed, self.k_slow,
                         self.slow_accel, self.goal_tolerance, self.brake_accel,
                         self.pass_offset, self.pass_clearance, self.pass_range,
                         float(self.heading_speed_factor), float(self.braking_profile),
                         self.pass_wall_room])


def slow_down(speed, params: NominalParams) -> np.ndarray:
    """The slow-down nominal ``[a, omega]`` at ``speed`` (m/s); (k, 2) for k speeds."""
    speeds = np.asarray(speed, dtype=float)
    u = np.empty(speeds.shape + (2,))
    _slow_downs(speeds.reshape(-1), params.k_slow, params.slow_accel, u.reshape(-1, 2))
    return u


@compiled_helper
def wrap_angle(angle):
    """Angle(s) wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def nominal_control(state, path: RobotPath | None, params: NominalParams, clustered: bool = False,
                    bodies=(), exclude: int = -1, walls=()) -> np.ndarray:
    """Nominal ``[a, omega]`` of a robot in ``state`` ``[x, y, theta, v]`` following ``path``
    (slow-down without an ``ok`` path). ``bodies`` (n, 3): positions and speeds (m/s) of
    other robots and humans, or (n, 2) positions of moving ones, used only for passing;
    ``bodies[exclude]`` is left out (e.g. the robot itself). ``walls`` (R, 2): the robot's
    wall ray hits in ray order (world frame, m), used only for the room to pass."""
    if not has_path(path):
        return slow_down(state[3], params)
    bodies = _with_speeds(bodies)
    walls = np.ascontiguousarray(np.asarray(walls, dtype=float).reshape(-1, 2))
    return np.array(_nominal_entry(float(state[0]), float(state[1]), float(state[2]),
                                   float(state[3]), path.points, path.stop_at_end, clustered,
                                   bodies, exclude, walls, np.ones(len(walls), dtype=np.bool_),
                                   params.gains))


def _with_speeds(bodies) -> np.ndarray:
    """``bodies`` as an (n, 3) array ``[x, y, speed]``; (n, 2) positions are moving."""
    bodies = np.asarray(bodies, dtype=float)
    if bodies.size == 0 or bodies.shape[-1] == 2:
        bodies = bodies.reshape(-1, 2)
        return np.column_stack([bodies, np.full(len(bodies), np.inf)])
    return np.ascontiguousarray(bodies.reshape(-1, 3))


@compiled_helper
def nominal_inputs(states, paths, clustered, bodies, hits, hit_mask, gains, u):
    """``nominal_control`` of every robot ``states`` (N, 4) into ``u`` (N, 2), compiled:
    ``paths`` a ``PathArrays``, ``clustered`` (N,) bools, ``bodies`` (n, 3) whose first N
    are the robots (each robot leaves itself out), ``hits`` (N, R, 2) and ``hit_mask``
    (N, R) the wall rays (as from ``WallRays``), ``gains`` ``NominalParams.gains``."""
    points, start, ok, stop_at_end = paths
    for i in range(len(states)):
        x, y, theta, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
        if ok[i]:
            u[i, 0], u[i, 1] = _nominal(x, y, theta, v, points[start[i]:start[i + 1]],
                                        stop_at_end[i], clustered[i], bodies, i, hits[i],
                                        hit_mask[i], gains)
        else:
            u[i, 0], u[i, 1] = slow_down_input(v, gains)


@compiled_helper
def slow_down_input(speed, gains):
    """The slow-down nominal (a, omega) at ``speed`` (m/s), compiled (``gains``:
    ``NominalParams.gains``)."""
    return _slow_down(speed, gains[_K_SLOW], gains[_SLOW_ACCEL])


# Indices into ``NominalParams.gains``.
(_K_X, _K_V, _K_THETA, _LOOKAHEAD, _GATE, _GATE_CLUSTER, _MAX_SPEED, _K_SLOW, _SLOW_ACCEL,
 _GOAL_TOLERANCE, _BRAKE_ACCEL, _PASS_OFFSET, _PASS_CLEARANCE, _PASS_RANGE,
 _HEADING_SPEED_FACTOR, _BRAKING_PROFILE, _PASS_WALL_ROOM) = range(17)


@compiled_helper
def _slow_down(speed, k_slow, slow_accel):
    return min(max(-k_slow * speed, -slow_accel), slow_accel), 0.0


@numba.njit(cache=True)
def _slow_downs(speeds, k_slow, slow_accel, u):
    for i in range(len(speeds)):
        u[i, 0], u[i, 1] = _slow_down(speeds[i], k_slow, slow_accel)


@numba.njit(cache=True)
def _nominal_entry(x, y, theta, v, points, stop_at_end, clustered, bodies, exclude, walls,
                  wall_mask, gains):
    """``_nominal`` for Python, which cannot call a ``compiled_helper``."""
    return _nominal(x, y, theta, v, points, stop_at_end, clustered, bodies, exclude, walls,
                    wall_mask, gains)


@compiled_helper
def _nominal(x, y, theta, v, points, stop_at_end, clustered, bodies, exclude, walls,
             wall_mask, gains):
    """Nominal (a, omega) along a path of at least one point (see ``nominal_control``;
    ``walls`` (R, 2) the robot's wall ray hits, ``wall_mask`` (R,) those that hit)."""
    gx, gy, is_end, remaining = _local_goal(x, y, points, gains[_LOOKAHEAD])
    passing, px, py = _passing_goal(x, y, gx, gy, bodies, exclude, remaining, walls,
                                    wall_mask, gains)
    if passing:
        gx, gy, is_end = px, py, False
    gate = gains[_GATE_CLUSTER] if clustered else gains[_GATE]
    return _track(x, y, theta, v, gx, gy, is_end, stop_at_end, remaining, gate, gains)


@compiled_helper
def _local_goal(x, y, points, lookahead):
    """Where to drive along a path ``points`` (k, 2), k >= 1, from (x, y).

    The local goal is the first point of the path polyline at least ``lookahead`` from the
    robot, searching on from the robot's projection onto the nearest segment (for the dense
    paths a grid planner makes this is the paper's "first path point at least 0.5 m away"; for
    sparse paths it stays on the polyline instead of cutting corners). Without one it is the
    path end. Returns the goal (x, y), whether it is the path end, and the remaining path
    length from the projection to the end (m).
    """
    k = len(points)
    if k == 1:
        return points[0, 0], points[0, 1], True, math.hypot(x - points[0, 0], y - points[0, 1])
    nearest, t_nearest = segment_projection(x, y, points)
    remaining = 0.0
    for i in range(nearest, k - 1):
        length = math.sqrt(max((points[i + 1, 0] - points[i, 0]) ** 2
                               + (points[i + 1, 1] - points[i, 1]) ** 2, 1e-12))
        remaining += (1.0 - t_nearest) * length if i == nearest else length
    px = points[nearest, 0] + t_nearest * (points[nearest + 1, 0] - points[nearest, 0])
    py = points[nearest, 1] + t_nearest * (points[nearest + 1, 1] - points[nearest, 1])
    if math.hypot(x - px, y - py) >= lookahead:  # off the path: head back to it
        return px, py, remaining == 0.0, remaining
    # Per segment from the nearest on: the larger root s of |a + s d| = lookahead, a = start - p.
    for i in range(nearest, k - 1):
        ax, ay = points[i, 0] - x, points[i, 1] - y
        dx, dy = points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]
        length2 = max(dx * dx + dy * dy, 1e-12)
        b = (ax * dx + ay * dy) / length2
        c = (ax * ax + ay * ay - lookahead * lookahead) / length2
        if b * b - c >= 0.0:
            root = -b + math.sqrt(b * b - c)
            if root <= 1.0:
                return points[i, 0] + root * dx, points[i, 1] + root * dy, False, remaining
    return points[k - 1, 0], points[k - 1, 1], True, remaining


@compiled_helper
def _passing_goal(x, y, gx, gy, bodies, exclude, reach, walls, wall_mask, gains):
    """Whether a body (``[x, y, speed]`` (n, 3), but ``exclude``) stands in the lane from
    (x, y) towards the goal (gx, gy) no farther than ``reach`` (m), and then a point as far
    as the goal in the direction of the point ``pass_offset`` to the right of the nearest
    such body (to its left if it is at rest more than ``pass_clearance / 2`` right of the
    lane, or if that point has a wall (``walls``, ``wall_mask``: ``_wall_room``) nearer
    than ``pass_wall_room`` and the point to the left has more room)."""
    offset = gains[_PASS_OFFSET]
    dist = math.hypot(gx - x, gy - y)
    if offset <= 0.0 or len(bodies) == 0 or dist < 1e-9:
        return False, gx, gy
    ahead_x, ahead_y = (gx - x) / dist, (gy - y) / dist
    limit = min(gains[_PASS_RANGE], reach)
    nearest, along_min, lateral_min, speed = -1, math.inf, 0.0, 0.0
    for j in range(len(bodies)):
        if j == exclude:
            continue
        rx, ry = bodies[j, 0] - x, bodies[j, 1] - y
        along = rx * ahead_x + ry * ahead_y
        lateral = -rx * ahead_y + ry * ahead_x
        if 0.0 < along < limit and abs(lateral) < gains[_PASS_CLEARANCE] and along < along_min:
            nearest, along_min, lateral_min, speed = j, along, lateral, bodies[j, 2]
    if nearest < 0:
        return False, gx, gy
    if speed < ROBOT_STOPPED_SPEED and lateral_min < -0.5 * gains[_PASS_CLEARANCE]:
        offset = -offset
    elif len(walls):
        right = _wall_room(x + along_min * ahead_x - (lateral_min - offset) * ahead_y,
                           y + along_min * ahead_y + (lateral_min - offset) * ahead_x,
                           walls, wall_mask)
        if right < gains[_PASS_WALL_ROOM]:
            left = _wall_room(x + along_min * ahead_x - (lateral_min + offset) * ahead_y,
                              y + along_min * ahead_y + (lateral_min + offset) * ahead_x,
                              walls, wall_mask)
            if left > right:
                offset = -offset
    aim_x = along_min * ahead_x - (lateral_min - offset) * ahead_y
    aim_y = along_min * ahead_y + (lateral_min - offset) * ahead_x
    # As far away as the goal, so that passing changes the heading but not the speed.
    scale = dist / math.hypot(aim_x, aim_y)
    return True, x + aim_x * scale, y + aim_y * scale


@compiled_helper
def _wall_room(px, py, walls, mask):
    """Distance (m) from (px, py) to the walls as a robot's wall rays see them: ``walls``
    (R, 2) its ray hits in ray order, ``mask`` (R,) the rays that hit; the wall between
    neighbouring hits is taken as straight (inf without hits)."""
    room, count = math.inf, len(walls)
    for r in range(count):
        if not mask[r]:
            continue
        ax, ay = walls[r, 0], walls[r, 1]
        room = min(room, math.hypot(px - ax, py - ay))
        n = (r + 1) % count
        if count > 1 and mask[n]:
            dx, dy = walls[n, 0] - ax, walls[n, 1] - ay
            f = min(max(((px - ax) * dx + (py - ay) * dy) / max(dx * dx + dy * dy, 1e-12),
                        0.0), 1.0)
            room = min(room, math.hypot(px - ax - f * dx, py - ay - f * dy))
    return room


@compiled_helper
def _track(x, y, theta, v, gx, gy, is_end, has_stop, remaining, heading_gate, gains):
    """Nominal (a, omega) driving towards the goal (gx, gy). ``has_stop``: the robot must
    stop ``remaining`` m ahead along the path; ``is_end``: the goal is that stop."""
    dx, dy = gx - x, gy - y
    dist = math.hypot(dx, dy)
    if is_end and dist <= gains[_GOAL_TOLERANCE]:
        return slow_down_input(v, gains)
    heading_error = wrap_angle(math.atan2(dy, dx) - theta)
    v_des, feedforward = min(gains[_K_X] * dist, gains[_MAX_SPEED]), 0.0
    if has_stop and gains[_BRAKING_PROFILE] > 0.0:
        # The braking profile to the stop; it governs the final approach, where k_x dist
        # would ask for more than max_accel. Its deceleration is fed forward so the speed
        # does not lag behind it.
        brake = gains[_BRAKE_ACCEL]
        v_stop = math.sqrt(2.0 * brake * max(remaining, dist if is_end else 0.0))
        if v_stop < v_des or is_end:
            v_des, feedforward = min(v_stop, gains[_MAX_SPEED]), -brake
    if abs(heading_error) > heading_gate:
        v_des, feedforward = 0.0, 0.0
    elif gains[_HEADING_SPEED_FACTOR] > 0.0:
        v_des *= math.cos(heading_error)
    return gains[_K_V] * (v_des - v) + feedforward, gains[_K_THETA] * heading_error
