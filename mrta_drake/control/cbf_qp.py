"""Second-order control barrier functions for dynamic unicycles and the QP that enforces them.

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
point, with ``b = -(2 |r_dot|^2 + (a1 + a2) h_dot + a1 a2 h)``. Each row is divided by
``|r|`` (m) so that rows near and far are equally scaled for the solver.

The QP, for k robots solved jointly (u stacked ``[a_0, omega_0, a_1, ...]``)::

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
from functools import cached_property

import numba
import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver, SolverOptions

from mrta_drake.control.nominal import NominalParams, wrap_angle
from mrta_drake.world.obstacles import cast_rays_into

SOLVERS = ("clarabel", "osqp")
COORDINATION_MODES = ("clusters", "decentralized", "centralized")
FOLLOWER_RULES = ("all", "in_the_way")  # which cluster followers get the slow-down nominal
WALL, HUMAN, ROBOT = 0, 1, 2  # row kinds
_MIN_SCALE = 1e-3  # m; rows for points closer than this are scaled as if at this distance
_PAD = 4  # row counts are padded to a multiple of this so that few programs are built


@dataclass(frozen=True)
class CbfParams(NominalParams):
    """All parameters of the CBF controllers: the nominal control's (``NominalParams``) plus
    safety distances (m, from the robot centre to a wall ray hit, a human centre or another
    robot centre), CBF rates ``alpha1``, ``alpha2`` per obstacle kind (1/s; defaults from the
    paper), the slack weight, the wall rays, the coordination mode (``clusters``,
    ``decentralized`` or ``centralized``), the cluster radius (m), the QP solver
    (``clarabel`` or ``osqp``) and the leader rule's name (a key of
    ``clusters.LEADER_RULES``: ``priority`` or ``distance_to_goal``).

    ``followers``: which cluster members other than the leader get the slow-down nominal.
    ``all`` (the paper): every one. ``in_the_way`` (default): only a member in conflict
    with an active member ranked above it in the cluster order, i.e. within
    ``yield_clearance`` (m) of that member's path ahead (its next ``yield_horizon`` m), or
    with that member within ``yield_clearance`` of its own path ahead, unless it drives the
    same way there (one follows the other); the others follow their paths (the cluster's
    joint QP still keeps them all apart). Why: clusters are
    transitive, so in a busy corridor one spans many robots for long; with ``all`` a robot
    4 m from a leader, out of everyone's way, stood for 38 s (one of the 20-seed sweep's
    deadlocks)."""

    safety_distance_human: float = 0.6
    safety_distance_wall: float = 0.6
    safety_distance_robot: float = 0.6
    alpha1_human: float = 1.0
    alpha2_human: float = 2.0
    alpha1_wall: float = 2.0
    alpha2_wall: float = 6.0
    alpha1_robot: float = 2.0
    alpha2_robot: float = 5.0
    slack_weight: float = 1e4  # linear penalty per unit of slack (scaled rows, m/s^2)
    ray_count: int = 12
    ray_spacing: float = math.pi / 6  # rad between neighbouring rays
    ray_start: float = 0.0  # rad, direction of the first ray
    rays_in_body_frame: bool = False  # False: ray directions fixed in the world frame
    ray_range: float = 10.0  # m
    coordination: str = "clusters"
    cluster_radius: float = 4.0  # m; also the range of robot-pair rows
    solver: str = "clarabel"
    leader_rule: str = "priority"
    followers: str = "in_the_way"
    yield_clearance: float = 1.0  # m
    yield_horizon: float = 3.0  # m
    # m; a robot this near the end of its stop-at-end path is done and leads no cluster (a
    # queue slot or room point too near a wall can be unreachable by a few centimetres).
    arrival_radius: float = 0.5
    # A cluster leader standing (|v| < stall_speed, m/s) this long (s) while active passes the
    # lead on (clusters.leader_stall_times): a follower in its way may need to move first.
    stall_time: float = 3.0
    stall_speed: float = 0.05
    # Commands computed at a tick reach robots updated at the same instants one tick later;
    # plan from the state predicted for then (see ClusterCbfController).
    predict_latency: bool = True

    def __post_init__(self):
        if self.coordination not in COORDINATION_MODES:
            raise ValueError(f"coordination must be one of {COORDINATION_MODES}, "
                             f"got {self.coordination!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.followers not in FOLLOWER_RULES:
            raise ValueError(f"followers must be one of {FOLLOWER_RULES}, "
                             f"got {self.followers!r}")

    @cached_property
    def _row_params(self) -> np.ndarray:
        """Safety distance, alpha1, alpha2 of walls, humans, robots, then the cluster radius,
        for the compiled row kernel."""
        return np.array([self.safety_distance_wall, self.alpha1_wall, self.alpha2_wall,
                         self.safety_distance_human, self.alpha1_human, self.alpha2_human,
                         self.safety_distance_robot, self.alpha1_robot, self.alpha2_robot,
                         self.cluster_radius])

    def ray_angles(self) -> np.ndarray:
        """Ray directions (rad): world frame, or offsets from the heading in the body frame."""
        return self.ray_start + self.ray_spacing * np.arange(self.ray_count)


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
    h, h_dot, drift, own_a, own_w, rx, ry, distance = _point_terms(
        *(np.ascontiguousarray(a) for a in (p[..., 0], p[..., 1], heading, v, o[..., 0],
                                            o[..., 1], w[..., 0], w[..., 1])),
        float(safety_distance))
    own = np.stack([own_a, own_w], axis=-1)
    return BarrierTerms(h, h_dot, drift, own, np.zeros_like(own), np.stack([rx, ry], axis=-1),
                        distance)


def pair_barrier(state_i, state_j, safety_distance):
    """Barrier terms of robot pairs; ``state_i``, ``state_j`` (m, 4) ``[x, y, theta, v]``.
    ``own`` are the coefficients of robot i's input, ``other`` those of robot j's."""
    si = np.atleast_2d(np.asarray(state_i, dtype=float))
    sj = np.atleast_2d(np.asarray(state_j, dtype=float))
    vj = sj[:, 3]
    terms = point_barrier(si[:, :2], si[:, 2], si[:, 3], sj[:, :2],
                          np.stack([vj * np.cos(sj[:, 2]), vj * np.sin(sj[:, 2])], axis=-1),
                          safety_distance)
    other = np.stack(_pair_other(*(np.ascontiguousarray(a) for a in (
        terms.offset[:, 0], terms.offset[:, 1], sj[:, 2], vj))), axis=-1)
    return BarrierTerms(terms.h, terms.h_dot, terms.drift, terms.own, other, terms.offset,
                        terms.distance)


def cbf_rhs(terms: BarrierTerms, alpha1: float, alpha2: float) -> np.ndarray:
    """``b`` of the unscaled rows ``own.u + other.u_j >= b``."""
    return _rhs(terms.drift, terms.h_dot, terms.h, float(alpha1), float(alpha2))


# The formulas above, compiled; each works on scalars (in the row kernel) and on arrays.


@numba.njit(cache=True)
def _point_terms(px, py, heading, v, ox, oy, wx, wy, safety_distance):
    """h, h_dot, drift, the coefficients of [a, omega], r = p - o and |r| (see the module
    docstring)."""
    c, s = np.cos(heading), np.sin(heading)
    rx, ry = px - ox, py - oy
    vx, vy = v * c - wx, v * s - wy
    r2 = rx * rx + ry * ry
    return (r2 - safety_distance * safety_distance, 2.0 * (rx * vx + ry * vy),
            2.0 * (vx * vx + vy * vy), 2.0 * (rx * c + ry * s), 2.0 * v * (ry * c - rx * s),
            rx, ry, np.sqrt(r2))


@numba.njit(cache=True)
def _pair_other(rx, ry, heading_j, v_j):
    """The coefficients of robot j's [a, omega] in a pair row, r = p_i - p_j."""
    c, s = np.cos(heading_j), np.sin(heading_j)
    return -2.0 * (rx * c + ry * s), -2.0 * v_j * (ry * c - rx * s)


@numba.njit(cache=True)
def _rhs(drift, h_dot, h, alpha1, alpha2):
    return -(drift + (alpha1 + alpha2) * h_dot + alpha1 * alpha2 * h)


class WallRays:
    """Wall rays of robots against the world's ``Obstacles`` (None: no walls).

    Calling it with robot states (N, 4) returns the ray hits (N, R, 2) in the world frame and a
    mask (N, R) of rays that hit within ``ray_range``.
    """

    def __init__(self, obstacles, params: CbfParams):
        self._params = params
        self._obstacles = obstacles if obstacles is not None and len(obstacles) else None
        self._angles = params.ray_angles()

    def __call__(self, states) -> tuple[np.ndarray, np.ndarray]:
        p = self._params
        states = np.ascontiguousarray(states, dtype=float).reshape(-1, 4)
        shape = (len(states), p.ray_count)
        if self._obstacles is None or p.ray_count == 0:
            return np.zeros(shape + (2,)), np.zeros(shape, dtype=bool)
        hits, mask = np.empty(shape + (2,)), np.empty(shape, dtype=bool)
        _wall_hits(states, self._angles, p.rays_in_body_frame, float(p.ray_range),
                   self._obstacles.compiled, hits, mask)
        return hits, mask


@numba.njit(cache=True)
def _wall_hits(states, angles, in_body_frame, ray_range, obstacles, hits, mask):
    """``WallRays`` into ``hits`` (N, R, 2) and ``mask`` (N, R) (``obstacles``:
    ``Obstacles.compiled``)."""
    n, rays = len(states), len(angles)
    dx, dy = np.empty((n, rays)), np.empty((n, rays))
    for i in range(n):
        for r in range(rays):
            angle = angles[r] + states[i, 2] if in_body_frame else angles[r]
            dx[i, r], dy[i, r] = np.cos(angle), np.sin(angle)
    dist = np.full((n, rays), ray_range)
    cast_rays_into(states[:, :2].copy(), dx, dy, *obstacles, dist)
    for i in range(n):
        for r in range(rays):
            hits[i, r, 0] = states[i, 0] + dist[i, r] * dx[i, r]
            hits[i, r, 1] = states[i, 1] + dist[i, r] * dy[i, r]
            mask[i, r] = dist[i, r] < ray_range


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


@dataclass(frozen=True)
class QpProblem:
    """One QP of a tick: the robots whose inputs it decides (``members``), their nominal
    inputs and hard bounds (k, 2) ``[a, omega]``, and the safety rows."""

    members: tuple[int, ...]
    u_nominal: np.ndarray
    rows: SafetyRows
    lower: np.ndarray
    upper: np.ndarray


def safety_rows(states, hits, hit_mask, human_positions, human_velocities, movers,
                params: CbfParams) -> SafetyRows:
    """All safety rows of one QP whose inputs are those of the robots in ``states`` (k, 4):

    - each robot's wall rows at its own ``hits`` (k, R, 2) where ``hit_mask`` (k, R);
    - each robot's rows for every human (positions and velocities (M, 2));
    - each robot's rows for every robot in ``movers`` (q, 4) within ``cluster_radius``: robots
      outside the QP, predicted at constant velocity;
    - one row per pair of robots in the QP within ``cluster_radius``, in both robots' inputs.
    """
    states = np.ascontiguousarray(states, dtype=float).reshape(-1, 4)
    k = len(states)
    hits = np.ascontiguousarray(hits, dtype=float).reshape(k, -1, 2)
    mask = np.ascontiguousarray(hit_mask, dtype=bool).reshape(k, -1)
    humans = np.ascontiguousarray(human_positions, dtype=float).reshape(-1, 2)
    movers = np.ascontiguousarray(movers, dtype=float).reshape(-1, 4)
    m = _count_rows(states, mask, len(humans), movers, params.cluster_radius**2)
    rows = _empty_rows(m, k)
    _fill_rows(states, hits, mask, humans,
               np.ascontiguousarray(human_velocities, dtype=float).reshape(-1, 2), movers,
               params._row_params, *rows)
    return SafetyRows(*rows)


@dataclass(frozen=True, eq=False)
class TickQps:
    """The QPs of one tick (``qp_problems``), kept as the compiled kernel made them: group g's
    robots ``groups[g]``, rows ``G[G_start[g]:G_start[g + 1]]`` (flattened) and ``b``, ...
    ``[row_start[g]:row_start[g + 1]]``; whether it needs a solver; the steered nominal
    inputs, bounds and ``settled`` inputs (N, 2) of ``qp_problems``."""

    groups: tuple[tuple[int, ...], ...]
    u_nominal: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    G: np.ndarray
    G_start: np.ndarray
    rows: tuple[np.ndarray, ...]  # b, kind, h, member, other, normal
    row_start: np.ndarray
    needs_solver: np.ndarray
    settled: np.ndarray

    def problem(self, g: int) -> QpProblem:
        r0, r1 = self.row_start[g], self.row_start[g + 1]
        u_nominal, G, b, lower, upper = self.arrays(g)
        rows = SafetyRows(G, b, *(a[r0:r1] for a in self.rows[1:]))
        return QpProblem(self.groups[g], u_nominal, rows, lower, upper)

    def arrays(self, g: int) -> tuple[np.ndarray, ...]:
        """Group g's QP as ``CbfQp.solve`` takes it: nominal inputs, ``G``, ``b``, bounds."""
        group, r0, r1 = self.groups[g], self.row_start[g], self.row_start[g + 1]
        index = list(group)
        return (self.u_nominal[index], self.G[self.G_start[g]:self.G_start[g + 1]].reshape(
            r1 - r0, 2 * len(group)), self.rows[0][r0:r1], self.lower[index], self.upper[index])

    @property
    def problems(self) -> tuple[QpProblem, ...]:
        """Every group's QP."""
        return tuple(self.problem(g) for g in range(len(self.groups)))

    def to_solve(self) -> tuple[int, ...]:
        """The groups whose QPs need a solver."""
        return tuple(np.flatnonzero(self.needs_solver).tolist())


_NO_MOVERS = np.zeros((0, 4))


def qp_problems(groups, states, hits, hit_mask, human_positions, human_velocities, movers,
                u_nominal, lower, upper, params: CbfParams, members=None,
                group_start=None) -> TickQps:
    """The QPs of one tick for robots ``states`` (N, 4) solved in ``groups`` (tuples of robot
    indices), with their wall ``hits`` and ``hit_mask`` (as from ``WallRays``), the humans,
    ``movers`` (one (q, 4) array per group as in ``safety_rows``; None: none) and hard
    bounds ``lower``, ``upper`` (N, 2). Each group's rows are ``safety_rows``; its robots'
    ``u_nominal`` (a float array (N, 2)) are steered in place (``steer_blocked``). A group
    needs a solver when its clipped nominal breaks a row (or its rows are not finite: the
    solve then fails); for the robots of the others the clipped nominal is the optimum
    (``CbfQp.solve`` would return it): ``settled`` holds it, and zero for robots in no
    group. ``members`` and ``group_start``: the groups as arrays (group g is
    ``members[group_start[g]:group_start[g + 1]]``), if the caller has them."""
    groups = tuple(tuple(group) for group in groups)
    if members is None:
        members = np.array([i for group in groups for i in group], dtype=np.int64)
        group_start = np.cumsum([0] + [len(group) for group in groups], dtype=np.int64)
    if movers is None:
        movers, mover_start = _NO_MOVERS, np.zeros(len(groups) + 1, dtype=np.int64)
    else:
        mover_start = np.array([0] + [len(m) for m in movers], dtype=np.int64).cumsum()
        movers = np.concatenate([np.zeros((0, 4)), *movers]).reshape(-1, 4)
    n = len(states)
    lower, upper = (np.ascontiguousarray(a, dtype=float) for a in (lower, upper))
    settled = np.zeros((n, 2))
    G, G_start, *rows, row_start, needs_solver = _group_rows(
        *(np.ascontiguousarray(a, dtype=float).reshape(shape) for a, shape in (
            (states, (n, 4)), (hits, (n, -1, 2)), (human_positions, (-1, 2)),
            (human_velocities, (-1, 2)))),
        np.ascontiguousarray(hit_mask, dtype=bool).reshape(n, -1), members, group_start,
        movers, mover_start, params._row_params, params.stall_speed, params.k_theta,
        u_nominal, lower, upper, settled)
    return TickQps(groups, u_nominal, lower, upper, G, G_start, tuple(rows), row_start,
                   needs_solver, settled)


@numba.njit(cache=True)
def _group_rows(states, hits, humans, human_velocities, mask, members, group_start, movers,
                mover_start, params, stall_speed, k_theta, u_nominal, lower, upper, settled):
    """``qp_problems`` for the groups ``members[group_start[g]:group_start[g + 1]]`` with
    movers ``movers[mover_start[g]:mover_start[g + 1]]``: every group's rows (G of group g
    flattened at ``G[G_start[g]:G_start[g + 1]]``, the other arrays at
    ``row_start[g]:row_start[g + 1]``), steering ``u_nominal`` in place, and whether each
    group needs its QP solved; ``settled`` gets the others' clipped nominal inputs."""
    groups = len(group_start) - 1
    radius2 = params[9] * params[9]
    row_start = np.zeros(groups + 1, dtype=np.int64)
    G_start = np.zeros(groups + 1, dtype=np.int64)
    for g in range(groups):
        index = members[group_start[g]:group_start[g + 1]]
        m = _count_rows(states[index], mask[index], len(humans),
                        movers[mover_start[g]:mover_start[g + 1]], radius2)
        row_start[g + 1] = row_start[g] + m
        G_start[g + 1] = G_start[g] + m * 2 * len(index)
    G = np.zeros(G_start[groups])
    b, kind, h, member, other, normal = _empty_rows(row_start[groups], 0)[1:]
    needs_qp = np.zeros(groups, dtype=np.bool_)
    for g in range(groups):
        index = members[group_start[g]:group_start[g + 1]]
        k, r0, r1 = len(index), row_start[g], row_start[g + 1]
        G_g = G[G_start[g]:G_start[g + 1]].reshape((r1 - r0, 2 * k))
        group_states = states[index]
        _fill_rows(group_states, hits[index], mask[index], humans, human_velocities,
                   movers[mover_start[g]:mover_start[g + 1]], params, G_g, b[r0:r1],
                   kind[r0:r1], h[r0:r1], member[r0:r1], other[r0:r1], normal[r0:r1])
        u = u_nominal[index]
        _steer(u, group_states, G_g, b[r0:r1], member[r0:r1], other[r0:r1], normal[r0:r1],
               stall_speed, k_theta)
        u_nominal[index] = u
        flat = u.ravel()
        clipped = np.minimum(np.maximum(flat, lower[index].ravel()), upper[index].ravel())
        finite, optimal = _check_nominal(G_g, b[r0:r1], flat, clipped)
        needs_qp[g] = not (finite and optimal)
        if not needs_qp[g]:
            settled[index] = clipped.reshape((k, 2))
    return G, G_start, b, kind, h, member, other, normal, row_start, needs_qp


@numba.njit(cache=True)
def _empty_rows(m, k):
    return (np.zeros((m, 2 * k)), np.empty(m), np.empty(m, np.int64), np.empty(m),
            np.empty(m, np.int64), np.full(m, -1, np.int64), np.empty((m, 2)))


@numba.njit(cache=True)
def _count_rows(states, mask, humans, movers, radius2):
    """The number of rows ``safety_rows`` makes (``humans``: how many)."""
    k = len(states)
    m = mask.sum() + k * humans
    for i in range(k):
        for q in range(len(movers)):
            m += _near(states[i], movers[q], radius2)
        for j in range(i + 1, k):
            m += _near(states[i], states[j], radius2)
    return m


@numba.njit(cache=True)
def _near(a, b, radius2):
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 <= radius2


@numba.njit(cache=True)
def _fill_rows(states, hits, mask, humans, human_velocities, movers, params, G, b, kind, h,
               member, other, normal):
    """Fills ``safety_rows``' arrays (``params``: ``CbfParams._row_params``; ``G`` zero).
    Rows in order: walls, humans, movers (each robot by robot), pairs."""
    k, rays, count = len(states), mask.shape[1], len(humans)
    radius2 = params[9] * params[9]
    row = 0
    for what in (WALL, HUMAN, ROBOT):
        base = 3 * what  # safety distance, alpha1, alpha2 of this kind in params
        points = rays if what == WALL else count if what == HUMAN else len(movers)
        for i in range(k):
            x, y, theta, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
            for q in range(points):
                if what == WALL:
                    if not mask[i, q]:
                        continue
                    terms = _point_terms(x, y, theta, v, hits[i, q, 0], hits[i, q, 1], 0.0, 0.0,
                                         params[base])
                elif what == HUMAN:
                    terms = _point_terms(x, y, theta, v, humans[q, 0], humans[q, 1],
                                         human_velocities[q, 0], human_velocities[q, 1],
                                         params[base])
                else:
                    if not _near(states[i], movers[q], radius2):
                        continue
                    speed, heading = movers[q, 3], movers[q, 2]
                    terms = _point_terms(x, y, theta, v, movers[q, 0], movers[q, 1],
                                         speed * np.cos(heading), speed * np.sin(heading),
                                         params[base])
                _put_row(row, terms, i, -1, 0.0, 0.0, what, params[base + 1],
                         params[base + 2], G, b, kind, h, member, other, normal)
                row += 1
    for i in range(k):
        for j in range(i + 1, k):
            if not _near(states[i], states[j], radius2):
                continue
            speed, heading = states[j, 3], states[j, 2]
            terms = _point_terms(states[i, 0], states[i, 1], states[i, 2], states[i, 3],
                                 states[j, 0], states[j, 1], speed * np.cos(heading),
                                 speed * np.sin(heading), params[6])
            other_a, other_w = _pair_other(terms[5], terms[6], heading, speed)
            _put_row(row, terms, i, j, other_a, other_w, ROBOT, params[7], params[8], G, b,
                     kind, h, member, other, normal)
            row += 1


@numba.njit(cache=True)
def _put_row(row, terms, i, j, other_a, other_w, what, alpha1, alpha2, G, b, kind, h, member,
             other, normal):
    """Row ``row`` for robot i (and robot j >= 0 of a pair), divided by |r| (at least
    ``_MIN_SCALE``) so that rows near and far are equally scaled."""
    value, h_dot, drift, own_a, own_w, rx, ry, distance = terms
    scale = 1.0 / max(distance, _MIN_SCALE)
    G[row, 2 * i], G[row, 2 * i + 1] = own_a * scale, own_w * scale
    if j >= 0:
        G[row, 2 * j], G[row, 2 * j + 1] = other_a * scale, other_w * scale
    b[row] = _rhs(drift, h_dot, value, alpha1, alpha2) * scale
    kind[row], h[row], member[row], other[row] = what, value, i, j
    normal[row, 0], normal[row, 1] = rx * scale, ry * scale


def steer_blocked(u_nominal, states, rows: SafetyRows, params: CbfParams) -> np.ndarray:
    """The nominal inputs (k, 2) of a QP's robots ``states`` (k, 4), with a new yaw rate for
    every robot that stands (|v| < ``stall_speed``) and whose nominal push forward breaks a
    safety row: it turns towards the tangent of the most blocking obstacle point nearer its
    goal heading. (Beyond the paper: a standing unicycle's yaw rate does not enter any row,
    so its QP has no reason to turn, and a robot nosing into a corner would wait forever.)"""
    u = np.array(u_nominal, dtype=float).reshape(-1, 2)
    _steer(u, np.ascontiguousarray(states, dtype=float).reshape(-1, 4),
           *(np.ascontiguousarray(a) for a in (rows.G, rows.b, rows.member, rows.other,
                                               rows.normal)),
           params.stall_speed, params.k_theta)
    return u


@numba.njit(cache=True)
def _steer(u, states, G, b, member, other, normal, stall_speed, k_theta):
    """``steer_blocked`` in place on ``u`` (k, 2)."""
    violation = np.empty(len(b))
    for row in range(len(b)):
        value = 0.0
        for column in range(G.shape[1]):
            value += G[row, column] * u[column // 2, column % 2]
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
        best = obstacle + 0.5 * math.pi
        if abs(wrap_angle(obstacle - 0.5 * math.pi - desired)) < abs(wrap_angle(best - desired)):
            best = obstacle - 0.5 * math.pi
        u[j, 1] = k_theta * wrap_angle(best - states[j, 2])


def barrier_minima(states, hits, hit_mask, human_positions,
                   params: CbfParams) -> tuple[float, float, float]:
    """Smallest barrier value h (m^2; inf when none) over all robots ``states`` (N, 4) and
    their wall ``hits`` (N, R, 2) where ``hit_mask``, over all robot-human pairs and over all
    robot pairs."""
    p = np.ascontiguousarray(np.asarray(states, dtype=float).reshape(-1, 4)[:, :2])
    wall, human, robot = _min_squared_distances(
        p, np.ascontiguousarray(hits, dtype=float).reshape(len(p), -1, 2),
        np.ascontiguousarray(hit_mask, dtype=bool).reshape(len(p), -1),
        np.ascontiguousarray(human_positions, dtype=float).reshape(-1, 2))
    return (wall - params.safety_distance_wall**2, human - params.safety_distance_human**2,
            robot - params.safety_distance_robot**2)


@numba.njit(cache=True)
def _min_squared_distances(p, hits, mask, humans):
    """Smallest squared distance (m^2; inf when none) from a robot (p (N, 2)) to one of its
    wall hits, to a human, to another robot."""
    wall = human = robot = math.inf
    for i in range(len(p)):
        for r in range(mask.shape[1]):
            if mask[i, r]:
                wall = min(wall, (hits[i, r, 0] - p[i, 0]) ** 2 + (hits[i, r, 1] - p[i, 1]) ** 2)
        for q in range(len(humans)):
            human = min(human, (p[i, 0] - humans[q, 0]) ** 2 + (p[i, 1] - humans[q, 1]) ** 2)
        for j in range(i + 1, len(p)):
            robot = min(robot, (p[i, 0] - p[j, 0]) ** 2 + (p[i, 1] - p[j, 1]) ** 2)
    return wall, human, robot


@dataclass(frozen=True)
class QpSolution:
    """``u`` (k, 2) inputs ``[a, omega]``; ``slack`` (m,) per safety row (scaled units, m/s^2);
    ``success`` False when the solver failed (``u`` is then meaningless); ``solve_time`` s of
    wall-clock time (the solver runs on the calling thread); ``solved`` False when the
    clipped nominal was already optimal (no solver call)."""

    u: np.ndarray
    slack: np.ndarray
    success: bool
    solve_time: float
    solved: bool = True


class _Program:
    """One MathematicalProgram for k robots and m safety rows, built once; each solve only
    updates coefficients and bounds."""

    def __init__(self, k: int, m: int, slack_weight: float):
        self.prog = MathematicalProgram()
        self.u = self.prog.NewContinuousVariables(2 * k, "u")
        self.s = self.prog.NewContinuousVariables(m, "s")
        self.hessian = 2.0 * np.eye(2 * k)
        self.linear = np.zeros(2 * k)
        self.cost = self.prog.AddQuadraticCost(self.hessian, self.linear, self.u, is_convex=True)
        self.box = self.prog.AddBoundingBoxConstraint(np.zeros(2 * k), np.zeros(2 * k), self.u)
        self.A = np.hstack([np.zeros((m, 2 * k)), np.eye(m)])
        self.lower = np.zeros(m)
        self.upper = np.full(m, np.inf)
        self.prog.AddLinearCost(np.full(m, slack_weight), 0.0, self.s)
        self.prog.AddBoundingBoxConstraint(np.zeros(m), self.upper, self.s)
        self.rows = self.prog.AddLinearConstraint(self.A, self.lower, self.upper,
                                                  np.concatenate([self.u, self.s]))
        # The decision variables are u, then s: a solution vector reads [u, s].
        self.cost_evaluator, self.box_evaluator, self.rows_evaluator = (
            binding.evaluator() for binding in (self.cost, self.box, self.rows))


class CbfQp:
    """Solves the CBF QP above with Clarabel or OSQP (through Drake), reusing one program per
    problem size (k robots, m rows)."""

    def __init__(self, solver: str = "clarabel", slack_weight: float = 1e4):
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        self.solver_name = solver
        self.slack_weight = float(slack_weight)
        self._solver = ClarabelSolver() if solver == "clarabel" else OsqpSolver()
        self._options = SolverOptions()
        if solver == "osqp":
            # Drake's defaults (1e-5) leave visible slack on tight rows; polish snaps to the
            # active set.
            for name, value in (("eps_abs", 1e-7), ("eps_rel", 1e-7), ("polishing", 1),
                                ("max_iter", 20000)):
                self._options.SetOption(OsqpSolver.id(), name, value)
        self._programs: dict[tuple[int, int], _Program] = {}

    def solve(self, u_nominal, G, b, lower, upper) -> QpSolution:
        """``u_nominal``, ``lower``, ``upper`` (k, 2); rows ``G`` (m, 2k) u >= ``b`` (m,)."""
        u_nom = np.asarray(u_nominal, dtype=float).reshape(-1)
        lo = np.asarray(lower, dtype=float).reshape(-1)
        hi = np.asarray(upper, dtype=float).reshape(-1)
        G = np.asarray(G, dtype=float)
        b = np.asarray(b, dtype=float)
        k, m = len(u_nom) // 2, len(b)
        start = time.perf_counter()
        clipped, finite, optimal, kept = _prepare(u_nom, G, b, lo, hi)
        if not finite:
            return QpSolution(np.zeros((k, 2)), np.zeros(m), False, time.perf_counter() - start)
        if optimal:
            return QpSolution(clipped.reshape(k, 2), np.zeros(m), True,
                              time.perf_counter() - start, solved=False)
        size = -(-len(kept) // _PAD) * _PAD
        program = self._programs.get((k, size))
        if program is None:
            program = self._programs[(k, size)] = _Program(k, size, self.slack_weight)
        _load_program(u_nom, G, b, kept, program.linear, program.A, program.lower)
        program.cost_evaluator.UpdateCoefficients(program.hessian, program.linear, 0.0, True)
        program.box_evaluator.set_bounds(lo, hi)
        program.rows_evaluator.UpdateCoefficients(program.A, program.lower, program.upper)
        result = self._solver.Solve(program.prog, None, self._options)
        elapsed = time.perf_counter() - start
        if not result.is_success():
            return QpSolution(np.zeros((k, 2)), np.zeros(m), False, elapsed)
        x = result.GetSolution()
        u = np.minimum(np.maximum(x[: 2 * k], lo), hi)
        slack = np.zeros(m)
        slack[kept] = np.maximum(x[2 * k: 2 * k + len(kept)], 0.0)
        return QpSolution(u.reshape(k, 2), slack, True, elapsed)


@numba.njit(cache=True)
def _prepare(u_nominal, G, b, lower, upper):
    """The nominal clipped to the box [``lower``, ``upper``]; whether ``G``, ``b`` and
    ``u_nominal`` are finite; whether the clipped nominal then meets every row (it minimizes
    the cost over the box, so it is the QP's optimum and no solver call is needed); and the
    rows that some u in the box breaks (the others cannot change the optimum)."""
    clipped = np.minimum(np.maximum(u_nominal, lower), upper)
    finite, optimal = _check_nominal(G, b, u_nominal, clipped)
    kept = np.empty(len(b), np.int64)
    count = 0
    if finite and not optimal:
        least = np.empty(G.shape[1])  # each term's minimum over the box
        for row in range(len(b)):
            for c in range(G.shape[1]):
                least[c] = G[row, c] * (lower[c] if G[row, c] > 0.0 else upper[c])
            if _pairwise_sum(least) < b[row]:
                kept[count] = row
                count += 1
    return clipped, finite, optimal, kept[:count]


@numba.njit(cache=True)
def _pairwise_sum(a):
    """The sum of ``a`` exactly as numpy's ``sum`` adds it, so that decisions match numpy's
    to the bit: blocks of at most 128 with eight accumulators; a longer range is split in
    two (the first part a multiple of 8 long) and the parts' sums added."""
    if len(a) <= 128:
        return _block_sum(a, 0, len(a))
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def _load_program(u_nominal, G, b, kept, linear, A, lower):
    """A ``_Program``'s data for rows ``G`` u >= ``b`` of which those ``kept`` are the
    first rows of ``A`` (the rest read 0 >= -1), and the linear cost of ``u_nominal``."""
    columns = len(u_nominal)
    for c in range(columns):
        linear[c] = u_nominal[c] * -2.0
    for row in range(len(lower)):
        keep = row < len(kept)
        for c in range(columns):
            A[row, c] = G[kept[row], c] if keep else 0.0
        lower[row] = b[kept[row]] if keep else -1.0


@numba.njit(cache=True)
def _check_nominal(G, b, u_nominal, clipped) -> tuple[bool, bool]:
    """Whether ``G``, ``b`` and ``u_nominal`` are all finite, and whether then ``clipped``
    meets every row ``G u >= b``."""
    if not (np.all(np.isfinite(G)) and np.all(np.isfinite(b))
            and np.all(np.isfinite(u_nominal))):
        return False, False
    for row in range(len(b)):
        value = 0.0
        for column in range(len(clipped)):
            value += G[row, column] * clipped[column]
        if not value >= b[row]:
            return True, False
    return True, True
