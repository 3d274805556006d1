"""Safe control of a fleet of dynamic unicycles with clustered CBF-QPs (the paper's controller)."""

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.control.active_set import NOT_LOADED, SOLVED, UNMET
from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.cluster_views import cluster_of, cut_off, group_of, views_disagree
from mrta_drake.control.clusters import LEADER_RULES, LeaderRule, clusters_of, stall_times_of
from mrta_drake.control.controller_common import controller_update, declare_controller_ports
from mrta_drake.control.followers import follower_rule_code
from mrta_drake.control.input_limits import limits_of
from mrta_drake.control.paths import PathArrays, robot_paths_of
from mrta_drake.control.qp_solver import SLACK_IN_USE, CbfQp
from mrta_drake.control.tick_kernel import (
    TickArrays,
    TickRobots,
    TickSettings,
    TickWorld,
    plan_tick,
)
from mrta_drake.control.tick_qps import QpProblem, TickQps, qp_problems
from mrta_drake.control.wall_rays import WallRays, rays_with_blockages
from mrta_drake.payloads import (
    NO_DISTURBANCES,
    NO_HUMANS,
    ROBOT_STATE_SIZE,
    CommandMessages,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    HumanStates,
    NetworkViews,
    frozen_array,
)


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
        """Every QP of the tick."""
        return self.qps.problems


@dataclass(frozen=True)
class SolvedQps:
    """Inputs ``u`` (N, 2) ``[a, omega]`` after a tick's solves: robots braked on solver
    failures, the largest slack, and per solver call (robots in the QP, s)."""

    u: np.ndarray
    failures: int
    max_slack: float
    calls: tuple[tuple[int, float], ...]


@dataclass(frozen=True)
class NetworkedTick:
    """One tick over a network: inputs ``u`` (N, 2), the telemetry, the commands sent to
    followers and each robot's stall time (s) as it sees itself."""

    u: np.ndarray
    telemetry: ControllerTelemetry
    messages: CommandMessages
    stall_times: np.ndarray


def _telemetry(time: float, plans_solved, clusters) -> ControllerTelemetry:
    """The telemetry of a tick that solved ``plans_solved`` ((TickPlan, SolvedQps) pairs)
    and formed ``clusters``."""
    if len(plans_solved) == 1:  # one plan (no network): its minima as they are
        barriers = plans_solved[0][0].min_barriers
    else:
        barriers = np.array([plan.min_barriers for plan, _ in plans_solved] or
                            [(np.inf,) * 3]).min(axis=0).tolist()
    deviations, slacks, failures, calls = [], [], 0, []
    for plan, solved in plans_solved:
        deviations.append(float(np.sqrt(((solved.u - plan.u_nominal) ** 2).sum(axis=1).max(
            initial=0.0))))
        slacks.append(solved.max_slack)
        failures += solved.failures
        calls.extend(solved.calls)
    return ControllerTelemetry(
        time=float(time), min_barrier_wall=barriers[0], min_barrier_human=barriers[1],
        min_barrier_robot=barriers[2], max_slack=max(slacks, default=0.0),
        control_deviation=max(deviations, default=0.0), clusters=clusters,
        solve_time=sum(t for _, t in calls), failures=failures, qp_calls=tuple(calls))


class ClusterCbfController(LeafSystem):
    """Commands for N robots from their paths, kept safe from walls, humans and each other by
    second-order control barrier functions (``mrta_drake.control.barriers``).

    .. pydrake_system::

        name: ClusterCbfController
        input_ports:
        - robot_state
        - paths
        - human_states (optional)
        - disturbances (optional)
        - network (optional)
        output_ports:
        - commands
        - telemetry
        - leader_commands

    Ports as in ``mrta_drake.control.controller_common``; robots in ``robot_names`` order.
    Over a network (input ``network``, ``NetworkViews``, connected when the scenario's
    ``communication:`` is not ideal) the controller is every robot's share of the protocol
    (``control_over_network``), and output ``leader_commands`` (``CommandMessages``) holds
    the commands the leaders sent their followers at the last tick; unconnected, one
    all-knowing controller forms the clusters from the true states.

    Every tick (fixed dt = 1 / rate_hz) each robot's nominal input ``[a, omega]`` follows its
    path (``mrta_drake.control.nominal``); QPs (``qp_solver``) then change the inputs as
    little as possible so that the barrier conditions hold, within the hard limits
    |a| <= max_accel, |omega| <= max_yaw_rate and min_speed <= v + a dt <= max_speed.
    ``params.coordination.mode``:

    - ``clusters`` (default): robots within ``cluster_radius`` (transitively) form a cluster;
      its leader (the first active member by the leader rule, but a robot whose path is
      ``yielding``, sent aside by the deadlock watchdog, first) keeps its nominal, its
      followers (``mrta_drake.control.followers``) get the slow-down nominal, and one joint QP
      over all members' inputs is solved, each member's wall and human rows evaluated at that
      member's own state. Lone robots solve their own QP.
    - ``decentralized``: each robot solves its own QP; other robots within ``cluster_radius``
      are obstacles moving at constant velocity.
    - ``centralized``: one QP over all robots' inputs.

    Beyond the paper, against deadlocks: a robot that stands and whose nominal push forward
    breaks a barrier row turns along the blocking obstacle (``steering``); a cluster leader
    that stands for ``stall_time`` passes the lead to the next member in turn
    (``clusters.stall_times_of``; the stall times are discrete state); robots within
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

    Disturbances: a broken-down robot is in no QP and gets the command [0, 0]; the others
    keep clear of it as of any robot outside their QP. A robot cut off from messages is in no
    cluster: the others form clusters and solve their QPs with its state as last broadcast
    before the outage (constant-velocity rows), and it solves its own QP alone against the
    others' states as it last heard them (``Disturbances.seen_by``), seeing walls and people
    with its own sensors, with the slow-down nominal: it brakes and stands until messages
    return, which keeps the others' last view of it within its braking distance of the
    truth (docs/control.md). Blockages stop the wall rays (``rays_with_blockages``).

    ``priorities``: per robot, smaller leads (default: robot order). ``leader_rule``: a
    function as in ``mrta_drake.control.clusters`` (default:
    ``params.coordination.leader_rule`` by name). ``obstacles``: the world's ``Obstacles``
    the wall rays are cast against (None: no walls).
    """

    def __init__(self, robot_names, obstacles=None, params: CbfParams | None = None,
                 priorities=None, leader_rule: LeaderRule | None = None, *, rate_hz: float):
        super().__init__()
        params = params or CbfParams()
        coordination = params.coordination
        if leader_rule is None and coordination.leader_rule not in LEADER_RULES:
            raise ValueError(f"leader_rule must be one of {sorted(LEADER_RULES)}, "
                             f"got {coordination.leader_rule!r}")
        self.robot_names = tuple(robot_names)
        self._n = len(self.robot_names)
        self._rays = WallRays(obstacles, params.sensing)
        self._params = params
        self._dt = 1.0 / rate_hz
        self._priorities = (np.arange(self._n, dtype=float) if priorities is None
                            else np.asarray(priorities, dtype=float).reshape(self._n))
        self._rule = leader_rule or LEADER_RULES[coordination.leader_rule]
        self._qp = CbfQp(params.qp.solver, params.qp.slack_weight)
        self._settings = tuple(TickSettings(  # a plain tuple, see plan
            self._priorities, params.nominal.gains, limits_of(params.nominal, self._dt),
            follower_rule_code(coordination.mode, coordination.followers),
            coordination.yield_clearance, coordination.head_on,
            coordination.yield_horizon,
            coordination.cluster_radius ** 2))
        self._ports = declare_controller_ports(self, self._n, self._dt, self._update)
        (self.robot_state_port, self.paths_port, self.human_states_port,
         self.disturbances_port, self.commands_port, self.telemetry_port) = self._ports.handles
        self._stall_index = self.DeclareDiscreteState(self._n)  # s stood as a blocked leader
        self._network = self.DeclareAbstractInputPort("network", Value[object](NetworkViews()))
        self._sent_index = self.DeclareDiscreteState(CommandMessages(
            -np.inf, (-1,) * self._n, np.zeros((self._n, 2))).as_vector())
        self.DeclareAbstractOutputPort(
            "leader_commands", lambda: Value[object](CommandMessages()),
            lambda context, output: output.set_value(CommandMessages.from_vector(
                context.get_discrete_state(self._sent_index).value())),
            prerequisites_of_calc={self.discrete_state_ticket(self._sent_index)})
        self._paths_seen: tuple[FleetPaths | None, tuple | None] = (None, None)
        self._nobody = np.zeros(self._n, dtype=bool)  # read only
        self._squared_distances = params.row_params[[0, 3, 6]] ** 2  # wall, human, robot; m^2

    @property
    def params(self) -> CbfParams:
        return self._params

    def plan(self, states, paths: FleetPaths, human_states: HumanStates | None = None,
             stall_times=None, disturbances: Disturbances | None = None) -> TickPlan:
        """What one tick solves for robots in ``states`` (N, 4): clusters, nominal inputs and
        the QPs of the coordination mode (``human_states`` None: no humans; ``stall_times``
        (N,) s each robot has stood as a blocked leader, see ``clusters.stall_times_of``;
        None: none; ``disturbances`` None: none, see the class docstring)."""
        humans = human_states or NO_HUMANS
        d = disturbances or NO_DISTURBANCES
        p, n = self._params, self._n
        states = np.ascontiguousarray(states, dtype=float).reshape(n, ROBOT_STATE_SIZE)
        path_arrays, yielding = self._path_arrays(paths)
        distances, active = path_arrays.progress(states, p.coordination.arrival_radius)
        alone = slowed = self._nobody  # in no cluster (broken down or cut off); slowed down
        if d.broken or d.cut_off:  # (cut off: the slow-down nominal)
            alone, slowed = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
            alone[list(d.broken + d.cut_off)] = slowed[list(d.cut_off)] = True
        shared = d.seen_by(states)
        keys = np.array(self._rule(self._priorities, distances), dtype=float)
        # A robot the deadlock watchdog sent aside leads its cluster: as a follower in the
        # others' way it would get the slow-down and never make way.
        keys[yielding] = -np.inf
        stalled = self._stalled(stall_times)
        stalled[yielding] = False  # a lead lost standing before the order does not count
        robots = TickRobots(states, np.ascontiguousarray(shared, dtype=float), keys, active,
                            stalled, ~alone, slowed)
        hits, mask = self._rays(states)
        if d.blockages:
            hits, mask = rays_with_blockages(states, hits, mask, d.blockages, p.sensing)
        world = TickWorld(np.ascontiguousarray(humans.positions, dtype=float).reshape(-1, 2),
                          np.ascontiguousarray(humans.velocities, dtype=float).reshape(-1, 2),
                          hits, mask)
        out = TickArrays.empty(n)
        # As plain tuples: numba types those in C, named ones in Python (~0.4 us a field).
        plan_tick(tuple(robots), tuple(world), tuple(path_arrays), self._settings, tuple(out))
        starts = out.starts[:out.labels.max(initial=-1) + 2]  # clusters are numbered 0, 1, ...
        clusters = clusters_of(out.order, starts)
        groups, members, group_start = self._groups(clusters, out.order, starts, d, alone)
        qps = qp_problems(groups, states, hits, mask, world.human_positions,
                          world.human_velocities, self._movers(groups, states, shared, d),
                          out.u_nominal, out.lower, out.upper, p, members, group_start)
        wall, human, robot = (out.minima - self._squared_distances).tolist()
        return TickPlan(clusters, active, out.u_nominal, qps, (wall, human, robot), out.order,
                        starts)

    def _groups(self, clusters, order, starts, d: Disturbances, alone):
        """The robots solved together (tuples of indices) in the coordination mode, and,
        when they are the clusters, the clusters as arrays (``order``, ``starts``)."""
        n, mode = self._n, self._params.coordination.mode
        members, group_start = None, None
        if mode == "clusters":
            groups, members, group_start = clusters, order, starts
        elif mode == "decentralized":
            groups = tuple((i,) for i in range(n))
        elif not (d.broken or d.cut_off):
            groups = (tuple(range(n)),)
        else:
            groups = (tuple(i for i in range(n) if not alone[i]),) + tuple(
                (i,) for i in d.cut_off)
        if d.broken or d.cut_off:
            groups = tuple(g for g in groups if g and not set(g) & set(d.broken))
            members, group_start = None, None
        return groups, members, group_start

    def _movers(self, groups, states, shared, d: Disturbances):
        """Per group, the robots outside it that its QP keeps clear of as moving obstacles
        (as its first robot knows them); None: none."""
        if not (self._params.coordination.mode == "decentralized" or d.broken or d.cut_off):
            return None
        views = {i: d.seen_by(states, i) for i in d.cut_off}
        return [np.delete(views.get(group[0], shared), list(group), axis=0) for group in groups]

    def _stalled(self, stall_times) -> np.ndarray:
        """(N,) whether each robot has stood ``stall_time`` as a blocked leader and so hands
        the lead on (never with ``stalled_leader_hands_on`` off; ``stall_times`` None: none
        has)."""
        c = self._params.coordination
        if stall_times is None or not c.stalled_leader_hands_on:
            return np.zeros(self._n, dtype=bool)
        return np.asarray(stall_times) >= c.stall_time

    def _path_arrays(self, paths: FleetPaths) -> tuple[PathArrays, list[int]]:
        """The arrays of ``paths`` and the robots whose path is ``yielding``."""
        # Paths change at the planner's rate, not every tick; payloads are immutable, so the
        # arrays of the last FleetPaths seen are reused while it is the same object.
        if paths is not self._paths_seen[0]:
            robot_paths = robot_paths_of(paths, self._n)
            self._paths_seen = (paths, (PathArrays.of(robot_paths), [
                k for k, path in enumerate(robot_paths) if path is not None and path.yielding]))
        return self._paths_seen[1]

    def control(self, time: float, states, paths: FleetPaths,
                human_states: HumanStates | None = None, stall_times=None,
                disturbances: Disturbances | None = None
                ) -> tuple[np.ndarray, ControllerTelemetry]:
        """One tick without the systems framework: inputs ``[a, omega]`` (N, 2) for robots in
        ``states`` (N, 4), and the tick's telemetry (arguments as for ``plan``)."""
        return self._solve(time, self.plan(states, paths, human_states, stall_times,
                                           disturbances))

    def _solve(self, time: float, plan: TickPlan) -> tuple[np.ndarray, ControllerTelemetry]:
        solved = self._solved(plan, plan.qps.to_solve())
        return solved.u, _telemetry(time, ((plan, solved),), plan.clusters)

    def _solved(self, plan: TickPlan, groups, u_nominal=None) -> SolvedQps:
        """Every robot's input from ``plan``: its group's solution for ``groups`` (indices
        of ``plan.qps.groups``), the settled input otherwise. Only QPs whose clipped nominal
        breaks a row reach the solver (the rest are settled). ``u_nominal`` (N, 2): nominal
        inputs in place of the plan's, for ``groups``.

        With the plan's nominal inputs the QPs are first solved in one compiled call
        (``CbfQp.solve_all``, each QP timed as an equal share of it); only those whose rows
        need the slack go on to Clarabel, one by one."""
        qps = plan.qps
        u = qps.settled.copy()
        failures, max_slack, calls = 0, 0.0, []
        stands = qps.standing.tolist().__getitem__ if groups else None
        status, share = None, 0.0
        if u_nominal is None and groups:
            start = time.perf_counter()
            status = self._qp.solve_all(qps.data, qps.data_start, qps.kept_count, qps.sizes,
                                        qps.members, qps.group_start, u)
            share = (time.perf_counter() - start) / len(groups)
            status = None if status is None else status.tolist()
        for g in groups:
            if u_nominal is None and not qps.needs_solver[g]:
                continue
            members = list(qps.groups[g])
            if status is not None and status[g] == SOLVED:  # u holds its answer
                calls.append((len(members), share))
                continue
            # With a standing robot, rows that cannot all be met are solved with its turn
            # fixed (TickQps.turns_fixed): where the active set finds so, straight away.
            standing, start = any(map(stands, members)), time.perf_counter()
            if status is not None and status[g] != NOT_LOADED:  # the active set tried it
                solution = (None if standing and status[g] == UNMET
                            else self._qp.solve_with_slack(qps.loaded(g), start))
            elif u_nominal is None:
                solution = self._qp.solve_loaded(qps.loaded(g), unless_unmet=standing)
            else:
                nominal, G, b, lower, upper = qps.arrays(g)
                solution = self._qp.solve(u_nominal[members], G, b, lower, upper,
                                          unless_unmet=standing)
            seconds = share + (time.perf_counter() - start if solution is None
                               else solution.solve_time)
            if solution is None or (solution.success and solution.max_slack > SLACK_IN_USE
                                    and standing):
                nominal, G, b, lower, upper = qps.arrays(g)
                if u_nominal is not None:
                    nominal = u_nominal[members]
                solution = self._qp.solve(nominal, G, b,
                                          *qps.turns_fixed(g, nominal, lower, upper))
                seconds += solution.solve_time
            calls.append((len(members), seconds))
            if solution.success:
                u[members] = solution.u
                max_slack = max(max_slack, solution.max_slack)
            else:
                u[members] = np.stack([qps.lower[members, 0], np.zeros(len(members))],
                                      axis=1)
                failures += len(members)
        return SolvedQps(u, failures, max_slack, tuple(calls))

    def control_over_network(self, time: float, states, paths: FleetPaths,
                             human_states: HumanStates, stall, d: Disturbances,
                             views: NetworkViews) -> NetworkedTick:
        """One tick over a network: each robot plans from its own view (the others' states
        as last received, ``views``); a robot leading its cluster as it sees it solves the
        cluster's QP, applies its own input and sends the followers theirs; a follower
        solves its own QP against its view, with its leader's command as the nominal if
        that is fresh (the command, kept within the follower's own barriers), else with the
        slow-down nominal (it brakes)."""
        n = self._n
        seen_states = [views.view_of(i, states[i]) for i in range(n)]
        plans = [self.plan(view, paths, human_states, stall, d) for view in seen_states]
        seen = [cluster_of(plan.clusters, i) for i, plan in enumerate(plans)]
        u, leaders, sent = np.zeros((n, 2)), [-1] * n, np.zeros((n, 2))
        used, stale = [], 0
        for i, plan in enumerate(plans):
            leader, nominal = seen[i][0], None
            if i in d.broken:
                continue
            if leader != i:  # a follower: its own QP against what it last heard
                plan = self.plan(seen_states[i], paths, human_states, stall,
                                 cut_off(d, i, time, seen_states[i]))
                if views.fresh_command(i, leader):  # the command, kept within its barriers
                    nominal = np.zeros((n, 2))
                    nominal[i] = views.commands[i]
                else:  # no fresh command: brake
                    stale += 1
            solved = self._solved(plan, [group_of(plan.qps.groups, i)], nominal)
            u[i] = solved.u[i]
            for follower in seen[i][1:] if leader == i else ():
                leaders[follower], sent[follower] = i, solved.u[follower]
            used.append((plan, solved))
        telemetry = dataclasses.replace(
            _telemetry(time, used, tuple(s for i, s in enumerate(seen) if s[0] == i)),
            leader_disagreement=views_disagree(seen), stale_commands=stale)
        return NetworkedTick(u, telemetry, CommandMessages(float(time), tuple(leaders),
                                                           frozen_array(sent)),
                             self._stall_times_seen(stall, seen_states, plans))

    def _stall_times_seen(self, stall, seen_states, plans) -> np.ndarray:
        """Each robot's stall time (s) after this tick, as it sees itself: from its own view
        ``seen_states[i]`` and its plan ``plans[i]`` (``clusters.stall_times_of``)."""
        c = self._params.coordination
        return np.array([stall_times_of(
            stall, seen_states[i][:, 3], plan.cluster_order, plan.cluster_start, plan.active,
            self._dt, c.stall_time, c.stall_speed)[i] for i, plan in enumerate(plans)])

    def _update(self, context, discrete_state) -> None:
        p, stall = self._params, context.get_discrete_state(self._stall_index).value()

        def control(time, states, paths, human_states, disturbances):
            if self._network.HasValue(context):
                tick = self.control_over_network(time, states, paths, human_states, stall,
                                       disturbances, self._network.Eval(context))
                discrete_state.set_value(self._stall_index, tick.stall_times)
                discrete_state.set_value(self._sent_index, tick.messages.as_vector())
                return tick.u, tick.telemetry
            plan = self.plan(states, paths, human_states, stall, disturbances)
            discrete_state.set_value(self._stall_index, stall_times_of(
                stall, states[:, 3], plan.cluster_order, plan.cluster_start, plan.active,
                self._dt, p.coordination.stall_time, p.coordination.stall_speed))
            return self._solve(time, plan)

        controller_update(self._ports, context, discrete_state, control, p.nominal,
                          p.predict_latency)
