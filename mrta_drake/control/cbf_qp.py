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

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver, SolverOptions

from mrta_drake.control.nominal import NominalParams, wrap_angle

SOLVERS = ("clarabel", "osqp")
COORDINATION_MODES = ("clusters", "decentralized", "centralized")
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
    ``clusters.LEADER_RULES``: ``priority`` or ``distance_to_goal``)."""

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
    p = np.asarray(position, dtype=float)
    o = np.asarray(points, dtype=float)
    w = np.broadcast_to(np.asarray(point_velocities, dtype=float), o.shape)
    v = np.asarray(speed, dtype=float)
    c, s = np.cos(heading), np.sin(heading)
    rx, ry = p[..., 0] - o[..., 0], p[..., 1] - o[..., 1]
    vx, vy = v * c - w[..., 0], v * s - w[..., 1]
    r2 = rx * rx + ry * ry
    own = np.stack([2.0 * (rx * c + ry * s), 2.0 * v * (ry * c - rx * s)], axis=-1)
    return BarrierTerms(r2 - safety_distance**2, 2.0 * (rx * vx + ry * vy),
                        2.0 * (vx * vx + vy * vy), own, np.zeros_like(own),
                        np.stack([rx, ry], axis=-1), np.sqrt(r2))


def pair_barrier(state_i, state_j, safety_distance):
    """Barrier terms of robot pairs; ``state_i``, ``state_j`` (m, 4) ``[x, y, theta, v]``.
    ``own`` are the coefficients of robot i's input, ``other`` those of robot j's."""
    si = np.atleast_2d(np.asarray(state_i, dtype=float))
    sj = np.atleast_2d(np.asarray(state_j, dtype=float))
    cj, sn = np.cos(sj[:, 2]), np.sin(sj[:, 2])
    vj = sj[:, 3]
    terms = point_barrier(si[:, :2], si[:, 2], si[:, 3], sj[:, :2],
                          np.stack([vj * cj, vj * sn], axis=-1), safety_distance)
    rx, ry = si[:, 0] - sj[:, 0], si[:, 1] - sj[:, 1]
    other = np.stack([-2.0 * (rx * cj + ry * sn), -2.0 * vj * (ry * cj - rx * sn)], axis=-1)
    return BarrierTerms(terms.h, terms.h_dot, terms.drift, terms.own, other, terms.offset,
                        terms.distance)


def cbf_rhs(terms: BarrierTerms, alpha1: float, alpha2: float) -> np.ndarray:
    """``b`` of the unscaled rows ``own.u + other.u_j >= b``."""
    return -(terms.drift + (alpha1 + alpha2) * terms.h_dot + alpha1 * alpha2 * terms.h)


def row_scale(terms: BarrierTerms) -> np.ndarray:
    """Positive per-row factors (1/m) applied to a row and its right-hand side."""
    return 1.0 / np.maximum(terms.distance, _MIN_SCALE)


class WallRays:
    """Wall rays of robots against the world's ``Obstacles`` (None: no walls).

    Calling it with robot states (N, 4) returns the ray hits (N, R, 2) in the world frame and a
    mask (N, R) of rays that hit within ``ray_range``. Obstacles farther than ``ray_range``
    from every robot cannot be hit, so rays are cast against the near ones only; those subsets
    are kept for reuse (robots move little between ticks). The result is the same as casting
    against all obstacles.
    """

    _CACHE_SIZE = 256

    def __init__(self, obstacles, params: CbfParams):
        self._params = params
        self._obstacles = obstacles if obstacles is not None and len(obstacles) else None
        if self._obstacles is None:
            return
        boxes, cylinders = self._obstacles.boxes, self._obstacles.cylinders
        # Bounding circles: centre and radius of every box, then every cylinder.
        self._centers = np.array([b.center for b in boxes] + [c.center for c in cylinders],
                                 dtype=float).reshape(-1, 2)
        self._radii = np.array([0.5 * math.hypot(*b.size) for b in boxes]
                               + [c.radius for c in cylinders], dtype=float)
        self._subsets: dict[bytes, object] = {}

    def _near(self, positions):
        d = positions[:, None, :] - self._centers[None, :, :]
        reach = self._params.ray_range + self._radii
        near = np.any(np.sum(d * d, axis=-1) <= reach * reach, axis=0)
        key = near.tobytes()
        subset = self._subsets.get(key)
        if subset is None:
            if len(self._subsets) >= self._CACHE_SIZE:
                self._subsets.clear()
            boxes = self._obstacles.boxes
            subset = type(self._obstacles)(
                tuple(b for b, keep in zip(boxes, near, strict=False) if keep),
                tuple(c for c, keep in zip(self._obstacles.cylinders, near[len(boxes):],
                                           strict=True) if keep))
            self._subsets[key] = subset
        return subset

    def __call__(self, states) -> tuple[np.ndarray, np.ndarray]:
        p = self._params
        states = np.asarray(states, dtype=float).reshape(-1, 4)
        angles = np.broadcast_to(p.ray_angles(), (len(states), p.ray_count))
        if p.rays_in_body_frame:
            angles = angles + states[:, 2:3]
        if self._obstacles is None or p.ray_count == 0:
            return np.zeros(angles.shape + (2,)), np.zeros(angles.shape, dtype=bool)
        near = self._near(states[:, :2])
        if len(near) == 0:
            return np.zeros(angles.shape + (2,)), np.zeros(angles.shape, dtype=bool)
        dist = near.cast_rays(states[:, :2], angles, p.ray_range)
        directions = np.stack([np.cos(angles), np.sin(angles)], -1)
        return states[:, None, :2] + dist[..., None] * directions, dist < p.ray_range


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


def _rows(terms: BarrierTerms, alphas, members, others, kind: int, k: int) -> SafetyRows:
    m = len(terms.h)
    scale = row_scale(terms)
    G = np.zeros((m, 2 * k))
    rows = np.arange(m)
    G[rows, 2 * members] = terms.own[:, 0] * scale
    G[rows, 2 * members + 1] = terms.own[:, 1] * scale
    if others is not None:
        G[rows, 2 * others] = terms.other[:, 0] * scale
        G[rows, 2 * others + 1] = terms.other[:, 1] * scale
    return SafetyRows(G, cbf_rhs(terms, *alphas) * scale, np.full(m, kind), terms.h,
                      np.asarray(members), np.full(m, -1) if others is None else others,
                      terms.offset * scale[:, None])


def safety_rows(states, hits, hit_mask, human_positions, human_velocities, movers,
                params: CbfParams) -> SafetyRows:
    """All safety rows of one QP whose inputs are those of the robots in ``states`` (k, 4):

    - each robot's wall rows at its own ``hits`` (k, R, 2) where ``hit_mask`` (k, R);
    - each robot's rows for every human (positions and velocities (M, 2));
    - each robot's rows for every robot in ``movers`` (q, 4) within ``cluster_radius``: robots
      outside the QP, predicted at constant velocity;
    - one row per pair of robots in the QP within ``cluster_radius``, in both robots' inputs.
    """
    states = np.asarray(states, dtype=float).reshape(-1, 4)
    k = len(states)
    parts = []
    member, ray = np.nonzero(hit_mask)
    if len(member):
        terms = point_barrier(states[member, :2], states[member, 2], states[member, 3],
                              hits[member, ray], 0.0, params.safety_distance_wall)
        parts.append(_rows(terms, (params.alpha1_wall, params.alpha2_wall), member, None, WALL, k))
    humans = np.asarray(human_positions, dtype=float).reshape(-1, 2)
    if len(humans):
        member = np.repeat(np.arange(k), len(humans))
        index = np.tile(np.arange(len(humans)), k)
        velocities = np.asarray(human_velocities, dtype=float).reshape(-1, 2)
        terms = point_barrier(states[member, :2], states[member, 2], states[member, 3],
                              humans[index], velocities[index], params.safety_distance_human)
        parts.append(_rows(terms, (params.alpha1_human, params.alpha2_human), member, None,
                           HUMAN, k))
    movers = np.asarray(movers, dtype=float).reshape(-1, 4)
    if len(movers):
        member, index = np.nonzero(np.sum((states[:, None, :2] - movers[None, :, :2]) ** 2, -1)
                                   <= params.cluster_radius**2)
        if len(member):
            mv = movers[index]
            velocity = mv[:, 3:4] * np.stack([np.cos(mv[:, 2]), np.sin(mv[:, 2])], -1)
            terms = point_barrier(states[member, :2], states[member, 2], states[member, 3],
                                  mv[:, :2], velocity, params.safety_distance_robot)
            parts.append(_rows(terms, (params.alpha1_robot, params.alpha2_robot), member,
                               None, ROBOT, k))
    if k > 1:
        i, j = np.triu_indices(k, 1)
        near = np.sum((states[i, :2] - states[j, :2]) ** 2, -1) <= params.cluster_radius**2
        i, j = i[near], j[near]
        if len(i):
            terms = pair_barrier(states[i], states[j], params.safety_distance_robot)
            parts.append(_rows(terms, (params.alpha1_robot, params.alpha2_robot), i, j, ROBOT, k))
    if not parts:
        none = np.zeros(0, dtype=int)
        return SafetyRows(np.zeros((0, 2 * k)), np.zeros(0), none, np.zeros(0), none, none,
                          np.zeros((0, 2)))
    return SafetyRows(*(np.concatenate([getattr(p, f.name) for p in parts])
                        for f in dataclasses.fields(SafetyRows)))


def steer_blocked(u_nominal, states, rows: SafetyRows, params: CbfParams) -> np.ndarray:
    """The nominal inputs (k, 2) of a QP's robots ``states`` (k, 4), with a new yaw rate for
    every robot that stands (|v| < ``stall_speed``) and whose nominal push forward breaks a
    safety row: it turns towards the tangent of the most blocking obstacle point nearer its
    goal heading. (Beyond the paper: a standing unicycle's yaw rate does not enter any row,
    so its QP has no reason to turn, and a robot nosing into a corner would wait forever.)"""
    u = np.array(u_nominal, dtype=float).reshape(-1, 2)
    if len(rows.b) == 0:
        return u
    states = np.asarray(states, dtype=float).reshape(-1, 4)
    violation = rows.G @ u.ravel() - rows.b
    for j in np.flatnonzero((np.abs(states[:, 3]) < params.stall_speed) & (u[:, 0] > 0.0)):
        involved = (rows.member == j) | (rows.other == j)
        blocking = involved & (rows.G[:, 2 * j] < 0.0) & (violation < 0.0)
        if not np.any(blocking):
            continue
        row = int(np.argmin(np.where(blocking, violation, np.inf)))
        away = rows.normal[row] if rows.member[row] == j else -rows.normal[row]
        obstacle = math.atan2(-away[1], -away[0])
        desired = states[j, 2] + u[j, 1] / params.k_theta
        tangents = obstacle + np.array([0.5 * np.pi, -0.5 * np.pi])
        best = tangents[np.argmin(np.abs(wrap_angle(tangents - desired)))]
        u[j, 1] = params.k_theta * wrap_angle(best - states[j, 2])
    return u


def barrier_minima(states, hits, hit_mask, human_positions,
                   params: CbfParams) -> tuple[float, float, float]:
    """Smallest barrier value h (m^2; inf when none) over all robots ``states`` (N, 4) and
    their wall ``hits`` (N, R, 2) where ``hit_mask``, over all robot-human pairs and over all
    robot pairs."""
    p = np.asarray(states, dtype=float).reshape(-1, 4)[:, :2]
    wall = np.sum((hits - p[:, None, :]) ** 2, axis=-1)[hit_mask]
    humans = np.asarray(human_positions, dtype=float).reshape(-1, 2)
    human = np.sum((p[:, None, :] - humans[None, :, :]) ** 2, axis=-1)
    i, j = np.triu_indices(len(p), 1)
    robot = np.sum((p[i] - p[j]) ** 2, axis=-1)
    return (float(np.min(wall, initial=np.inf)) - params.safety_distance_wall**2,
            float(np.min(human, initial=np.inf)) - params.safety_distance_human**2,
            float(np.min(robot, initial=np.inf)) - params.safety_distance_robot**2)


@dataclass(frozen=True)
class QpSolution:
    """``u`` (k, 2) inputs ``[a, omega]``; ``slack`` (m,) per safety row (scaled units, m/s^2);
    ``success`` False when the solver failed (``u`` is then meaningless); ``solve_time`` s of
    CPU time; ``solved`` False when the clipped nominal was already optimal (no solver call)."""

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
        start = time.thread_time()
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(b)) and np.all(np.isfinite(u_nom))):
            return QpSolution(np.zeros((k, 2)), np.zeros(m), False, time.thread_time() - start)
        # The clipped nominal minimizes the cost over the box; if it also meets every row it
        # is the QP's optimum and no solver call is needed.
        clipped = np.clip(u_nom, lo, hi)
        if m == 0 or np.all(G @ clipped >= b):
            return QpSolution(clipped.reshape(k, 2), np.zeros(m), True,
                              time.thread_time() - start, solved=False)
        # Rows that hold for every u in the box cannot change the optimum: drop them.
        kept = np.flatnonzero(np.where(G > 0.0, G * lo, G * hi).sum(axis=1) < b)
        size = -(-len(kept) // _PAD) * _PAD
        program = self._programs.get((k, size))
        if program is None:
            program = self._programs[(k, size)] = _Program(k, size, self.slack_weight)
        np.multiply(u_nom, -2.0, out=program.linear)
        program.cost.evaluator().UpdateCoefficients(program.hessian, program.linear, 0.0, True)
        program.box.evaluator().set_bounds(lo, hi)
        program.A[:, : 2 * k] = 0.0
        program.A[: len(kept), : 2 * k] = G[kept]
        program.lower[:] = -1.0  # padding rows read 0 >= -1
        program.lower[: len(kept)] = b[kept]
        program.rows.evaluator().UpdateCoefficients(program.A, program.lower, program.upper)
        result = self._solver.Solve(program.prog, None, self._options)
        elapsed = time.thread_time() - start
        if not result.is_success():
            return QpSolution(np.zeros((k, 2)), np.zeros(m), False, elapsed)
        u = np.clip(result.GetSolution(program.u), lo, hi)
        slack = np.zeros(m)
        slack[kept] = np.maximum(result.GetSolution(program.s)[: len(kept)], 0.0)
        return QpSolution(u.reshape(k, 2), slack, True, elapsed)
