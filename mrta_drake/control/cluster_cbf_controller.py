"""Safe control of a fleet of dynamic unicycles with clustered CBF-QPs (the paper's controller)."""

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.control.cbf_qp import (
    FOLLOWER_RULES,
    CbfParams,
    CbfQp,
    QpProblem,
    TickQps,
    WallRays,
    _min_squared_distances,
    qp_problems,
)
from mrta_drake.control.clusters import (
    LEADER_RULES,
    LeaderRule,
    _cluster_order,
    _labels,
    clusters_of,
    stall_times_of,
)
from mrta_drake.control.nominal import (
    _K_SLOW,
    _SLOW_ACCEL,
    NominalParams,
    PathArrays,
    _nominals,
    _path_ahead_near,
    _slow_down,
    _travel_direction,
)
from mrta_drake.payloads import (
    NO_DISTURBANCES,
    NO_HUMANS,
    ROBOT_COMMAND_SIZE,
    ROBOT_STATE_SIZE,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    HumanStates,
    RobotPath,
)
from mrta_drake.robots.unicycle_robots import UnicycleParams, unicycle_step
from mrta_drake.scenario.disturbances import blockage_obstacles

__all__ = ["CbfParams", "ClusterCbfController", "QpProblem", "TickPlan"]

_TELEMETRY_FIELDS = ("time", "min_barrier_wall", "min_barrier_human", "min_barrier_robot",
                     "max_slack", "control_deviation", "solve_time", "failures")


@dataclass(frozen=True)
class TickPlan:
    """Everything one tick solves: clusters (leader first), which robots are active (N,),
    every robot's nominal input (N, 2) (followers' already the slow-down), the QPs (``qps``;
    ``problems`` lists them), and the smallest barrier values (wall, human, robot; m^2)."""

    clusters: tuple[tuple[int, ...], ...]
    active: np.ndarray
    u_nominal: np.ndarray
    qps: TickQps
    min_barriers: tuple[float, float, float]
    cluster_order: np.ndarray  # the clusters as arrays: cluster c is
    cluster_start: np.ndarray  # cluster_order[cluster_start[c]:cluster_start[c + 1]]

    @property
    def problems(self) -> tuple[QpProblem, ...]:
        return self.qps.problems


class ClusterCbfController(LeafSystem):
    """Commands for N robots from their paths, kept safe from walls, humans and each other by
    second-order control barrier functions (see ``mrta_drake.control.cbf_qp``).

    Every tick (fixed dt = 1 / rate_hz) each robot's nominal input ``[a, omega]`` follows its
    path (``mrta_drake.control.nominal``); QPs then change the inputs as little as possible so
    that the barrier conditions hold, within the hard limits |a| <= max_accel,
    |omega| <= max_yaw_rate and min_speed <= v + a dt <= max_speed. ``params.coordination``:

    - ``clusters`` (default): robots within ``cluster_radius`` (transitively) form a cluster;
      its leader (the first active member by the leader rule) keeps its nominal, the others
      get the slow-down nominal, and one joint QP over all members' inputs is solved, each
      member's wall and human rows evaluated at that member's own state. Lone robots solve
      their own QP.
    - ``decentralized``: each robot solves its own QP; other robots within ``cluster_radius``
      are obstacles moving at constant velocity.
    - ``centralized``: one QP over all robots' inputs.

    Beyond the paper, against deadlocks: a robot that stands and whose nominal push forward
    breaks a barrier row turns along the blocking obstacle (``cbf_qp.steer_blocked``); a
    cluster leader that stands for ``stall_time`` passes the lead to the next member in turn
    (``clusters.leader_stall_times``; the stall times are discrete state); robots within
    ``arrival_radius`` of their path end lead no cluster.

    A failed solve makes every robot of that QP brake at the acceleration limit (turning
    stops); it is counted in the telemetry's ``failures`` (robots braked) and the run goes on.

    Latency: a robot block updated at the same instants applies the commands stored at tick k
    only from tick k + 1 on (Drake evaluates all discrete updates of an instant on the state
    before it). With ``params.predict_latency`` the controller therefore plans from each
    robot's state predicted one tick ahead under the commands it is executing now (the same
    exact arc step as ``UnicycleRobots``); without it, the speed set-point v + a dt would
    lag and braking would be halved. Barrier values in the telemetry are those of the
    predicted states.

    Input ``robot_state`` (4N): [x, y, theta, v] per robot, world frame, m, rad, m/s.
    Input ``paths`` (FleetPaths): one path per robot, in robot order.
    Input ``humans`` (HumanStates): may be left unconnected (no humans).
    Output ``commands`` (2N): [v, omega] per robot, m/s and rad/s; v = v' + a dt with v' the
    speed when the command takes effect (see Latency).
    Output ``telemetry`` (ControllerTelemetry): the last tick's account.

    Input ``disturbances`` (Disturbances): optional (none). A broken-down robot is in no
    QP and gets the command [0, 0]; the others keep clear of it as of any robot outside
    their QP. A robot cut off from messages is in no cluster: the others form clusters and
    solve their QPs with its state as last broadcast before the outage (constant-velocity
    rows), and it solves its own QP alone against the others' states as it last heard them
    (``Disturbances.seen_by``), seeing walls and people with its own sensors, with the
    slow-down nominal: it brakes and stands until messages return. Why not drive on: with
    stale states on both sides, a robot driving on could run into robots that do not know
    where it is (in the example scenario, robot2 driving on through its outage overlapped
    another robot by 0.4 m); braking keeps the others' last view of it within its braking
    distance (v^2 / (2 slow_accel), 0.19 m at 0.75 m/s) of the truth, so their barriers
    still protect it, the fail-safe of fleets that lose their link. The outage costs the
    time it stands. Blockages stop the wall rays (``rays_with_blockages``).

    ``priorities``: per robot, smaller leads (default: robot order). ``leader_rule``: a
    function as in ``mrta_drake.control.clusters`` (default: ``params.leader_rule`` by name).
    ``obstacles``: the world's ``Obstacles`` the wall rays are cast against (None: no walls).
    """

    def __init__(self, names, obstacles=None, params: CbfParams | None = None, priorities=None,
                 rate_hz: float = 20.0, leader_rule: LeaderRule | None = None):
        super().__init__()
        params = params or CbfParams()
        if leader_rule is None and params.leader_rule not in LEADER_RULES:
            raise ValueError(f"leader_rule must be one of {sorted(LEADER_RULES)}, "
                             f"got {params.leader_rule!r}")
        self.names = tuple(names)
        self._n = len(self.names)
        self._rays = WallRays(obstacles, params)
        self._params = params
        self._dt = 1.0 / rate_hz
        self._priorities = np.arange(self._n, dtype=float) if priorities is None else \
            np.asarray(priorities, dtype=float).reshape(self._n)
        self._rule = leader_rule or LEADER_RULES[params.leader_rule]
        self._qp = CbfQp(params.solver, params.slack_weight)
        declare_controller_ports(self, self._n, self._dt, self._update)
        self._stall_index = self.DeclareDiscreteState(self._n)  # s stood as a blocked leader
        self._paths_seen: tuple[FleetPaths | None, PathArrays | None] = (None, None)
        self._bounds = np.array([params.max_accel, params.max_speed, params.min_speed,
                                 params.max_yaw_rate, self._dt])
        # Which followers slow down (_plan_inputs): none outside clusters mode, all, or those
        # in the way; and the clearance and horizon (m) of "in the way".
        self._follower_rule = (0 if params.coordination != "clusters"
                               else 1 + FOLLOWER_RULES.index(params.followers))
        self._yield = np.array([params.yield_clearance, params.yield_horizon])

    @property
    def params(self) -> CbfParams:
        return self._params

    def plan(self, states, paths: FleetPaths, humans: HumanStates | None = None,
             stall_times=None, disturbances: Disturbances | None = None) -> TickPlan:
        """What one tick solves for robots in ``states`` (N, 4): clusters, nominal inputs and
        the QPs of the coordination mode (``humans`` None: no humans; ``stall_times`` (N,)
        s each robot has stood as a blocked leader, see ``clusters.leader_stall_times``;
        None: none; ``disturbances`` None: none, see the class docstring)."""
        humans = humans or NO_HUMANS
        d = disturbances or NO_DISTURBANCES
        p, n = self._params, self._n
        states = np.ascontiguousarray(states, dtype=float).reshape(n, ROBOT_STATE_SIZE)
        path_arrays = self._path_arrays(paths)
        distances, active = path_arrays.progress(states, p.arrival_radius)
        keys = np.ascontiguousarray(self._rule(self._priorities, distances), dtype=float)
        stalled = (np.zeros(n, dtype=bool) if stall_times is None
                   else np.asarray(stall_times) >= p.stall_time)
        broken, cut_off = d.broken, d.cut_off
        alone = np.zeros(n, dtype=bool)  # robots in no cluster: broken down or cut off
        alone[list(broken + cut_off)] = True
        slowed = np.zeros(n, dtype=bool)  # cut-off robots get the slow-down nominal
        slowed[list(cut_off)] = True
        human_p = np.ascontiguousarray(humans.positions, dtype=float).reshape(-1, 2)
        human_v = np.ascontiguousarray(humans.velocities, dtype=float).reshape(-1, 2)
        shared = d.seen_by(states)
        hits, mask = self._rays(states)
        if d.blockages:
            hits, mask = rays_with_blockages(states, hits, mask, d.blockages, p)
        order, labels = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        starts = np.empty(n + 1, dtype=np.int64)
        u_nom, lower, upper = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2))
        minima = np.empty(3)
        _plan_inputs(states, np.ascontiguousarray(shared, dtype=float), human_p, human_v,
                     path_arrays.points, path_arrays.start, path_arrays.ok,
                     path_arrays.stop_at_end, keys, self._priorities, active, stalled, ~alone,
                     slowed,
                     self._follower_rule, self._yield, p.cluster_radius ** 2, p._gains,
                     self._bounds, hits, mask, order, labels, starts, u_nom, lower, upper,
                     minima)
        clusters = clusters_of(order, labels)
        starts = starts[:len(clusters) + 1]
        members, group_start = None, None
        if p.coordination == "clusters":
            groups, members, group_start = clusters, order, starts
        elif p.coordination == "decentralized":
            groups = tuple((i,) for i in range(n))
        elif not (broken or cut_off):
            groups = (tuple(range(n)),)
        else:
            groups = (tuple(i for i in range(n) if not alone[i]),) + tuple(
                (i,) for i in cut_off)
        if broken or cut_off:
            groups = tuple(g for g in groups if g and not set(g) & set(broken))
            members, group_start = None, None
        movers = None
        if p.coordination == "decentralized" or broken or cut_off:
            views = {i: d.seen_by(states, i) for i in cut_off}
            movers = [np.delete(views.get(group[0], shared), list(group), axis=0)
                      for group in groups]
        qps = qp_problems(groups, states, hits, mask, human_p, human_v, movers, u_nom, lower,
                          upper, p, members, group_start)
        safety = p._row_params
        wall, human, robot = (minima - safety[[0, 3, 6]] ** 2).tolist()
        return TickPlan(clusters, active, u_nom, qps, (wall, human, robot), order, starts)

    def _path_arrays(self, paths: FleetPaths) -> PathArrays:
        # Paths change at the planner's rate, not every tick; payloads are immutable, so the
        # arrays of the last FleetPaths seen are reused while it is the same object.
        if paths is not self._paths_seen[0]:
            self._paths_seen = (paths, PathArrays.of(robot_paths_of(paths, self._n)))
        return self._paths_seen[1]

    def control(self, time: float, states, paths: FleetPaths, humans: HumanStates | None = None,
                stall_times=None, disturbances: Disturbances | None = None
                ) -> tuple[np.ndarray, ControllerTelemetry]:
        """One tick without the systems framework: inputs ``[a, omega]`` (N, 2) for robots in
        ``states`` (N, 4), and the tick's telemetry (arguments as for ``plan``)."""
        return self._solve(time, self.plan(states, paths, humans, stall_times, disturbances))

    def _solve(self, time: float, plan: TickPlan) -> tuple[np.ndarray, ControllerTelemetry]:
        # Only QPs whose clipped nominal breaks a row reach the solver (the rest are settled).
        u = plan.qps.settled.copy()
        failures, solve_time, max_slack = 0, 0.0, 0.0
        for g in plan.qps.to_solve() if plan.qps.needs_solver.any() else ():
            members = list(plan.qps.groups[g])
            u_nominal, G, b, lower, upper = plan.qps.arrays(g)
            solution = self._qp.solve(u_nominal, G, b, lower, upper)
            solve_time += solution.solve_time
            if solution.success:
                u[members] = solution.u
                max_slack = max(max_slack, max(solution.slack.tolist(), default=0.0))
            else:
                u[members] = np.stack([lower[:, 0], np.zeros(len(members))], axis=1)
                failures += len(members)
        wall, human, robot = plan.min_barriers
        change = u - plan.u_nominal
        deviation = math.sqrt((change * change).sum(axis=1).max(initial=0.0))
        telemetry = ControllerTelemetry(
            time=float(time), min_barrier_wall=wall, min_barrier_human=human,
            min_barrier_robot=robot, max_slack=max_slack, control_deviation=deviation,
            clusters=plan.clusters, solve_time=solve_time, failures=failures)
        return u, telemetry

    def _update(self, context, discrete_state) -> None:
        p, stall = self._params, context.get_discrete_state(self._stall_index).value()

        def control(time, states, paths, humans, disturbances):
            plan = self.plan(states, paths, humans, stall, disturbances)
            discrete_state.set_value(self._stall_index, stall_times_of(
                stall, states[:, 3], plan.cluster_order, plan.cluster_start, plan.active,
                self._dt, p.stall_time, p.stall_speed))
            return self._solve(time, plan)

        controller_update(self, context, discrete_state, control, p, self._dt, self._n)


def input_bounds(states, params: NominalParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Hard bounds (N, 2) on ``[a, omega]`` for robots ``states`` (N, 4): |a| <= max_accel,
    |omega| <= max_yaw_rate, and the speed after one step of dt s within
    [min_speed, max_speed] as far as the acceleration limit allows."""
    states = np.ascontiguousarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
    lower, upper = np.empty((len(states), 2)), np.empty((len(states), 2))
    _input_bounds(states, params.max_accel, params.max_speed, params.min_speed,
                  params.max_yaw_rate, dt, lower, upper)
    return lower, upper


@numba.njit(cache=True)
def _input_bounds(states, a_max, max_speed, min_speed, max_yaw_rate, dt, lower, upper):
    for i in range(len(states)):
        v = states[i, 3]
        a_hi = min(max((max_speed - v) / dt, -a_max), a_max)
        lower[i, 0] = min(min(max((min_speed - v) / dt, -a_max), a_max), a_hi)
        upper[i, 0] = a_hi
        lower[i, 1], upper[i, 1] = -max_yaw_rate, max_yaw_rate


@numba.njit(cache=True)
def _plan_inputs(states, shared, humans, human_v, points, start, ok, stop_at_end, keys,
                 priorities, active, stalled, reachable, slowed, follower_rule, yield_params,
                 radius2, gains, bounds, hits, mask, order, labels, starts, u_nom, lower,
                 upper, minima):
    """The compiled part of ``ClusterCbfController.plan``: cluster ``labels`` and ``order``
    (``clusters.form_clusters``; cluster c is ``order[starts[c]:starts[c + 1]]``), nominal
    inputs ``u_nom`` (cluster members with the cluster gate, around the ``shared`` robot
    states and the ``humans`` at velocities ``human_v``; slow-down for the ``slowed``
    robots and the followers of ``follower_rule``: 0 none, 1 every cluster member but the
    leader, 2 those in the way (``_in_the_way``; ``yield_params``: clearance, horizon)),
    input bounds (``input_bounds``; ``bounds``: ``_bounds``) and the smallest squared
    distances to walls, humans and robots (``minima``)."""
    n = len(states)
    labels[:] = _labels(states[:, :2].copy(), radius2, reachable)
    order[:] = _cluster_order(labels, active, stalled, keys, priorities)
    size = np.zeros(n, dtype=np.int64)
    for i in range(n):
        size[labels[i]] += 1
    starts[0] = 0
    for c in range(n):
        starts[c + 1] = starts[c] + size[c]
    clustered = np.empty(n, dtype=np.bool_)
    for i in range(n):
        clustered[i] = size[labels[i]] > 1
    bodies = np.empty((n + len(humans), 3))  # x, y, speed
    bodies[:n, :2], bodies[:n, 2] = shared[:, :2], np.abs(shared[:, 3])
    for q in range(len(humans)):
        bodies[n + q, 0], bodies[n + q, 1] = humans[q, 0], humans[q, 1]
        bodies[n + q, 2] = math.hypot(human_v[q, 0], human_v[q, 1])
    _nominals(states, points, start, ok, stop_at_end, clustered, bodies, gains, u_nom)
    first = 0  # position in order of the current cluster's leader
    for k in range(n):
        i = order[k]
        follower = k > 0 and labels[order[k - 1]] == labels[i]
        if not follower:
            first = k
        if follower and follower_rule == 2:
            follower = _in_the_way(i, order[first:k], states, points, start, ok, active,
                                   yield_params[0], yield_params[1])
        if slowed[i] or (follower_rule > 0 and follower):
            u_nom[i] = _slow_down(states[i, 3], gains[_K_SLOW], gains[_SLOW_ACCEL])
    _input_bounds(states, bounds[0], bounds[1], bounds[2], bounds[3], bounds[4], lower, upper)
    minima[0], minima[1], minima[2] = _min_squared_distances(states[:, :2].copy(), hits, mask,
                                                             humans)


@numba.njit(cache=True)
def _in_the_way(i, above, states, points, start, ok, active, clearance, horizon):
    """Whether robot i and an active robot j of ``above`` (those ranked above it in its
    cluster) are in each other's way: either within ``clearance`` (m) of the other's path
    ahead (its next ``horizon`` m), unless it drives on that way too (within 60 degrees of
    the other's direction there: one follows the other, and the barriers keep the gap)."""
    x, y = states[i, 0], states[i, 1]
    own = points[start[i]:start[i + 1]]
    ix, iy = _travel_direction(x, y, own) if ok[i] else (0.0, 0.0)
    for j in above:
        if not active[j]:
            continue
        qx, qy = states[j, 0], states[j, 1]
        path = points[start[j]:start[j + 1]]
        near, ux, uy = _path_ahead_near(qx, qy, path, x, y, horizon, clearance)
        if near and ux * ix + uy * iy < _SAME_WAY:
            return True
        if ok[i]:
            near, ux, uy = _path_ahead_near(x, y, own, qx, qy, horizon, clearance)
            jx, jy = _travel_direction(qx, qy, path)
            if near and ux * jx + uy * jy < _SAME_WAY:
                return True
    return False


_SAME_WAY = 0.5  # cos 60 degrees: two directions this close are the same way (_in_the_way)


def predict_states(states, commands, params: NominalParams, dt: float) -> np.ndarray:
    """Robot ``states`` (N, 4) one tick of ``dt`` s later under ``commands`` (N, 2)
    ``[v, omega]``, by the robot block's own exact arc step with the controller's limits."""
    return unicycle_step(np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE),
                         np.asarray(commands, dtype=float).reshape(-1, ROBOT_COMMAND_SIZE),
                         _robot_limits(params), dt)


@functools.cache
def _robot_limits(params: NominalParams) -> UnicycleParams:
    """The controller's limits as a robot block's parameters (``predict_states``)."""
    return UnicycleParams(max_speed=params.max_speed,
                          max_reverse_speed=max(0.0, -params.min_speed),
                          max_acceleration=params.max_accel, max_yaw_rate=params.max_yaw_rate)


def controller_update(system, context, discrete_state, control, params: CbfParams, dt: float,
                      n: int) -> None:
    """The periodic update of a controller with ``declare_controller_ports``' ports and state:
    read the inputs, ``control(time, states, paths, humans, disturbances) -> (u, telemetry)``
    from the state the new commands will act on, store the commands (zero for broken-down
    robots) and the telemetry."""
    # The ports in the order declare_controller_ports declares them.
    state_port, paths_port, humans_port, disturbances_port = (
        system.get_input_port(k) for k in range(4))
    states = state_port.Eval(context).reshape(n, ROBOT_STATE_SIZE)
    paths = paths_port.Eval(context)
    humans = humans_port.Eval(context) if humans_port.HasValue(context) else NO_HUMANS
    disturbances = (disturbances_port.Eval(context) if disturbances_port.HasValue(context)
                    else NO_DISTURBANCES)
    if params.predict_latency:
        states = predict_states(states, context.get_discrete_state(0).value(), params, dt)
    u, telemetry = control(context.get_time(), states, paths, humans, disturbances)
    commands = np.empty((n, ROBOT_COMMAND_SIZE))
    commands[:, 0] = states[:, 3] + u[:, 0] * dt
    commands[:, 1] = u[:, 1]
    if disturbances.broken:
        commands[list(disturbances.broken)] = 0.0
    discrete_state.set_value(0, commands.ravel())
    discrete_state.set_value(1, _telemetry_vector(telemetry, n))


def rays_with_blockages(states, hits, mask, blockages, params: CbfParams
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Wall ray ``hits`` (N, R, 2) and ``mask`` (N, R) of robots ``states`` (N, 4) (as from
    ``WallRays``) with the rays also stopped by the boxes of ``blockages``
    (``payloads.Blockage``), except a box the robot is in: it drives out unhindered."""
    states = np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
    origins = states[:, :2]
    angles = np.broadcast_to(params.ray_angles(), (len(states), params.ray_count))
    if params.rays_in_body_frame:
        angles = angles + states[:, 2:3]
    directions = np.stack([np.cos(angles), np.sin(angles)], -1)
    reach = params.ray_range
    dist = np.where(mask, np.linalg.norm(hits - origins[:, None, :], axis=-1), reach)
    for blockage in blockages:
        near = blockage_obstacles((blockage,)).cast_rays(origins, angles, reach)
        near[blockage.contains(origins)] = reach
        nearer = near < dist
        hits = np.where(nearer[..., None], origins[:, None, :] + near[..., None] * directions,
                        hits)
        mask, dist = mask | nearer, np.minimum(dist, near)
    return hits, mask


def robot_paths_of(paths: FleetPaths, n: int) -> tuple[RobotPath | None, ...]:
    """The N robots' paths (all None for an empty FleetPaths: nothing planned yet)."""
    if len(paths.paths) not in (0, n):
        raise ValueError(f"paths: expected {n} robot paths, got {len(paths.paths)}")
    return tuple(paths.paths) if paths.paths else (None,) * n


def declare_controller_ports(system: LeafSystem, n: int, dt: float, update) -> None:
    """Declare the ports, state and ``update`` event of a controller for ``n`` robots ticking
    every ``dt`` s: discrete state group 0 holds the commands, group 1 the telemetry."""
    commands = system.DeclareDiscreteState(ROBOT_COMMAND_SIZE * n)
    telemetry = system.DeclareDiscreteState(_telemetry_vector(ControllerTelemetry(), n))
    system.DeclareVectorInputPort("robot_state", ROBOT_STATE_SIZE * n)
    system.DeclareAbstractInputPort("paths", Value[object](FleetPaths(())))
    system.DeclareAbstractInputPort("humans", Value[object](HumanStates()))
    system.DeclareAbstractInputPort("disturbances", Value[object](Disturbances()))
    system.DeclareStateOutputPort("commands", commands)
    system.DeclareAbstractOutputPort(
        "telemetry", lambda: Value[object](ControllerTelemetry()),
        lambda context, output: output.set_value(_telemetry_from_vector(
            context.get_discrete_state(telemetry).value(), n)),
        prerequisites_of_calc={system.discrete_state_ticket(telemetry)})
    system.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, update)


def _telemetry_vector(telemetry: ControllerTelemetry, n: int) -> np.ndarray:
    """Telemetry as numbers: the scalar fields, then the clusters' members one cluster after
    the other, then where each cluster ends in that list (both padded with -1 to n)."""
    k = len(_TELEMETRY_FIELDS)
    vector = np.full(k + 2 * n, -1.0)
    vector[:k] = [getattr(telemetry, name) for name in _TELEMETRY_FIELDS]
    members, ends = [], []
    for cluster in telemetry.clusters:
        members.extend(cluster)
        ends.append(len(members))
    vector[k:k + len(members)] = members
    vector[k + n:k + n + len(ends)] = ends
    return vector


def _telemetry_from_vector(vector, n: int) -> ControllerTelemetry:
    k = len(_TELEMETRY_FIELDS)
    fields = dict(zip(_TELEMETRY_FIELDS, vector[:k].tolist(), strict=True))
    fields["failures"] = int(fields["failures"])
    members = vector[k:k + n].astype(int).tolist()
    clusters, first = [], 0
    for end in vector[k + n:].astype(int).tolist():
        if end < 0:
            break
        clusters.append(tuple(members[first:end]))
        first = end
    return ControllerTelemetry(clusters=tuple(clusters), **fields)
