"""One planner block serving every robot, like the single shared Nav2 planner server."""

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.navigation.costmap import (
    MAX_NON_OBSTACLE,
    Costmap,
    CostmapParams,
    resolution_for,
)
from mrta_drake.navigation.grid_planner import GridPlanner, PlannerParams
from mrta_drake.payloads import (
    NO_BACK_OFFS,
    NO_DISTURBANCES,
    PATH_FAILED,
    PATH_IDLE,
    PATH_OK,
    ROBOT_STATE_SIZE,
    ROBOT_STOPPED_SPEED,
    BackOffOrders,
    Disturbances,
    FleetPaths,
    Relocations,
    RobotPath,
    WaypointTarget,
    frozen_array,
)
from mrta_drake.robots.relocation import Applied
from mrta_drake.scenario.disturbances import blockage_obstacles
from mrta_drake.stack.fleet_inputs import PerRobotInputs
from mrta_drake.world.obstacles import Cylinder, Obstacles

_COSTMAP_CACHE = 16  # costmaps with closures kept for reuse
_NO_POINTS = frozen_array(np.zeros((0, 2)))  # of every idle or failed path


@dataclass(frozen=True)
class PlannerServiceParams:
    """Costmap and planner parameters of the block (its rates are the scenario's
    ``rates.planner`` and ``rates.planner_target_check``). ``cost_resting_robots``: paths go
    around robots at rest (see ``PlannerService``; off: the static map only, as in the
    paper)."""

    costmap: CostmapParams = field(default_factory=CostmapParams)
    planner: PlannerParams = field(default_factory=PlannerParams)
    cost_resting_robots: bool = True


@dataclass(frozen=True)
class _ServiceState:
    """The block's abstract state: the paths it outputs, the targets they were planned
    for, the time (s) of the next periodic re-plan, what they were planned around
    (``PlannerService._closures``), the relocations seen (``Applied``; None before the
    first) and the indices of the robots whose target predates their relocation
    (``stale``)."""

    paths: FleetPaths
    targets: tuple[WaypointTarget | None, ...]
    next_replan: float
    closed: tuple = ()
    relocated: Applied | None = None
    stale: frozenset[int] = frozenset()

    def __deepcopy__(self, memo):
        # Everything in here is immutable, so Drake's per-update copy can share it.
        return self


class PlannerService(LeafSystem):
    """Plans a path for every robot with one shared ``GridPlanner``.

    .. pydrake_system::

        name: PlannerService
        input_ports:
        - robot_state
        - target_<robot>
        - fleet_targets (optional)
        - disturbances (optional)
        - back_offs (optional)
        - relocations (optional)
        output_ports:
        - paths

    Inputs: ``robot_state`` (vector, 4N: x, y, theta, v per robot, world frame, m, rad, m/s)
    and ``target_<robot>`` (abstract ``WaypointTarget``), one per robot in ``robot_names``
    order, all connected, or instead ``fleet_targets``, their tuple in that order
    (``stack.fleet_inputs``). Output: ``paths`` (abstract ``FleetPaths``), from the
    state.

    Every ``1 / target_check_rate_hz`` s an unrestricted update re-plans the robots whose
    target changed since their last plan, and every ``1 / replan_rate_hz`` s (at the first
    check tick at or after that time) all robots. A robot with an active target gets a path
    from its position through ``current`` and, unless it must stop there, on to ``next``. If
    the leg to ``current`` has no path the robot's path is ``failed`` (it waits; re-planned
    at the next periodic re-plan); if only the leg on to ``next`` fails the path ends at
    ``current``. Each failed leg adds one to ``FleetPaths.failures``. A path ends with a stop
    (``stop_at_end``) at ``next``, or at ``current`` when the target says so.

    Robots at rest: at each periodic re-plan (and when the disturbances change), every robot
    slower than ``ROBOT_STOPPED_SPEED`` that has an active target or is broken down makes the
    cells within the costmap's robot radius plus inflation radius of it (its position
    rounded to the costmap's cells) cost ``MAX_NON_OBSTACLE``: paths go around a robot
    standing in the way where there is room rather than run into it, and still reach a
    place it stands on or next to (the controller keeps the distance). Why: the controller
    only keeps robots apart; two robots whose paths run through each other (e.g. head-on
    along a wall) stop nose to nose and, with paths that never leave that line, stay there.
    A standing robot's own cells cost the same in every direction, so they do not bend its
    own path. With ``cost_resting_robots`` off only broken-down robots are costed.

    Optional input ``disturbances`` (abstract ``Disturbances``): while blockages are in force
    their boxes are obstacles of the costmap (``Costmap.with_obstacles``, recomputed around
    them only). When the costs change, every robot is re-planned at the next check tick. A
    robot caught inside a blockage has no path (failed) until it opens.

    Optional input ``back_offs`` (abstract ``BackOffOrders``, the deadlock watchdog's): a
    robot ordered to back off is planned to its spot, to stop there, instead of to its
    target, until the order ends; its path is marked ``yielding`` (the controller lets it
    lead its cluster).

    Optional input ``relocations`` (abstract ``Relocations``, the lift bank's): a robot
    whose relocation (a lift ride's end, to the cabin on another level) is new is planned
    for at the next check tick; while its target is the one it had before that relocation
    (set where it stood before, on the level it left: a path from where it stands now to
    it would fail) its path is idle, no failure, and it stands until its waypoint generator
    gives it a new target.
    """

    def __init__(self, planner: GridPlanner, robot_names: Sequence[str], *,
                 replan_rate_hz: float, target_check_rate_hz: float,
                 cost_resting_robots: bool = True):
        super().__init__()
        if not (replan_rate_hz > 0.0 and target_check_rate_hz > 0.0):
            raise ValueError("replan_rate_hz and target_check_rate_hz must be positive")
        self._planner = planner
        self._open_costmap = planner.base_costmap
        self._costmaps = {(): self._open_costmap}  # by closures (``_closures``)
        self._robots = tuple(robot_names)
        self._cost_resting_robots = cost_resting_robots
        self._replan_period = 1.0 / replan_rate_hz
        n = len(self._robots)
        initial = _ServiceState(
            FleetPaths(tuple(RobotPath(robot) for robot in self._robots)), (None,) * n, 0.0)
        self._state_index = self.DeclareAbstractState(Value[object](initial))
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * n))
        self._targets = PerRobotInputs(self, "target", "targets", self._robots, WaypointTarget)
        self._disturbances = self.DeclareAbstractInputPort(
            "disturbances", Value[object](Disturbances()))
        self._back_offs = self.DeclareAbstractInputPort(
            "back_offs", Value[object](BackOffOrders()))
        self._relocations = self.DeclareAbstractInputPort(
            "relocations", Value[object](Relocations()))
        self.DeclareAbstractOutputPort(
            "paths",
            lambda: Value[object](initial.paths),
            self._calc_paths,
            prerequisites_of_calc={self.abstract_state_ticket(self._state_index)},
        )
        self.DeclareInitializationUnrestrictedUpdateEvent(self._update)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / target_check_rate_hz, 0.0,
                                                    self._update)

    @classmethod
    def from_obstacles(cls, obstacles: Obstacles, bounds, robot_names: Sequence[str],
                       params: PlannerServiceParams = PlannerServiceParams(), *,
                       replan_rate_hz: float, target_check_rate_hz: float, floors=()
                       ) -> "PlannerService":
        """A block planning over ``obstacles`` rasterized on ``bounds`` = (x_min, x_max,
        y_min, y_max) (m) at the costmap's default resolution, coarser for very large
        worlds (``costmap.resolution_for``), and off the ``floors`` (``FloorPlan.floors``)
        where there are any."""
        costmap = Costmap.from_obstacles(obstacles, bounds, params.costmap,
                                         resolution_for(bounds), floors)
        return cls(GridPlanner(costmap, params.planner), robot_names,
                   replan_rate_hz=replan_rate_hz, target_check_rate_hz=target_check_rate_hz,
                   cost_resting_robots=params.cost_resting_robots)

    @property
    def planner(self) -> GridPlanner:
        return self._planner

    @property
    def robot_names(self) -> tuple[str, ...]:
        return self._robots

    def get_target_input_port(self, robot: str):
        return self._targets.ports[self._robots.index(robot)]

    def _calc_paths(self, context, output):
        output.set_value(context.get_abstract_state(self._state_index).get_value().paths)

    def _update(self, context, state):
        old = context.get_abstract_state(self._state_index).get_value()
        now = context.get_time()
        targets, backing = self._targets_now(context)
        disturbances = (self._disturbances.Eval(context) if self._disturbances.HasValue(context)
                        else NO_DISTURBANCES)
        periodic = now >= old.next_replan - 1e-9
        closed = self._closures(context, disturbances, targets, old.closed, periodic)
        replan_all = periodic or closed != old.closed
        # ``is`` first: an unchanged target is mostly the very same object.
        changed = {k for k, (target, was) in enumerate(zip(targets, old.targets, strict=True))
                   if target is not was and target != was}
        relocated, moved = self._relocated(context, old.relocated)
        stale = (old.stale | moved) - changed
        due = [k for k in range(len(targets)) if replan_all or k in changed or k in moved]
        if not due:
            return EventStatus.DidNothing()
        self._close(disturbances.blockages, closed)
        robot_state = self._robot_state.Eval(context)
        paths = list(old.paths.paths)
        failures = old.paths.failures
        for k in due:
            if k in stale:
                paths[k] = RobotPath(self._robots[k], PATH_IDLE, _NO_POINTS, planned_at=now)
                continue
            xy = robot_state[ROBOT_STATE_SIZE * k:ROBOT_STATE_SIZE * k + 2]
            paths[k], failed = self._plan(self._robots[k], xy, targets[k], now)
            if self._robots[k] in backing:
                paths[k] = replace(paths[k], yielding=True)
            failures += failed
        next_replan = old.next_replan
        if periodic:
            # Keep the period's phase, but never fall behind the clock.
            next_replan = max(next_replan + self._replan_period, now + 0.5 * self._replan_period)
        state.get_mutable_abstract_state(self._state_index).set_value(
            _ServiceState(FleetPaths(tuple(paths), failures), targets, next_replan, closed,
                          relocated, frozenset(stale)))
        return EventStatus.Succeeded()

    def _relocated(self, context, seen: Applied | None) -> tuple[Applied | None, set[int]]:
        """The relocations seen (``seen``: those known before, None for none), and the
        indices of the robots relocated since."""
        if not self._relocations.HasValue(context):
            return seen, set()
        relocations = self._relocations.Eval(context)
        if not any(relocations.moves):
            return seen, set()
        seen = seen or Applied((0,) * len(self._robots))
        moves = seen.new_moves(relocations)
        return seen.after(moves), {k for k, move in enumerate(moves) if move is not None}

    def _targets_now(self, context) -> tuple[tuple[WaypointTarget, ...], frozenset[str]]:
        """Each robot's target: its waypoint generator's, or its back-off spot while the
        watchdog orders one; and the robots backing off."""
        targets = self._targets.values(context)
        orders = (self._back_offs.Eval(context) if self._back_offs.HasValue(context)
                  else NO_BACK_OFFS)
        if not orders.active:
            return targets, frozenset()
        spots = {order.robot: order.point for order in orders.active}
        return tuple(WaypointTarget(t.robot, True, spots[t.robot], None, True)
                     if t.robot in spots else t for t in targets), frozenset(spots)

    def _closures(self, context, disturbances: Disturbances, targets, old: tuple,
                  periodic: bool) -> tuple:
        """What raises costs now: the blockages' names, the broken-down robots' indices and
        (index, x, y) of each robot at rest (see the class docstring; taken anew at periodic
        re-plans and when the other two change, else kept from ``old``), its position
        rounded to the costmap's cells (m); () for nothing."""
        broken = disturbances.broken
        disturbed = tuple(b.name for b in disturbances.blockages), broken
        if not periodic and disturbed == (old[:2] if old else ((), ())):
            return old
        states = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        res = self._open_costmap.resolution
        resting = tuple((k, round(states[k, 0] / res) * res, round(states[k, 1] / res) * res)
                        for k in range(len(self._robots))
                        if abs(states[k, 3]) < ROBOT_STOPPED_SPEED
                        and (k in broken or (self._cost_resting_robots and targets[k].active)))
        closed = (*disturbed, resting)
        return closed if any(closed) else ()

    def _close(self, blockages, closed: tuple) -> None:
        """Make the planner's costmap the open one with the ``closed`` cells (``_closures``,
        of ``blockages``) added. Costmaps are cached by closures and the planner switched to
        the state's before every use, so results never depend on what was planned before."""
        costmap = self._costmaps.get(closed)
        if costmap is None:
            costmap = self._open_costmap
            if blockages:
                costmap = costmap.with_obstacles(blockage_obstacles(blockages))
            if closed[2]:
                reach = costmap.params.robot_radius + costmap.params.inflation_radius
                costmap = costmap.with_obstacles(Obstacles(cylinders=tuple(
                    Cylinder(f"resting_{k}", (x, y), reach) for k, x, y in closed[2])),
                    MAX_NON_OBSTACLE)
            if len(self._costmaps) > _COSTMAP_CACHE:
                self._costmaps = {(): self._open_costmap}
            self._costmaps[closed] = costmap
        if self._planner.costmap is not costmap:
            self._planner.use_costmap(costmap)

    def _plan(self, robot: str, xy: np.ndarray, target: WaypointTarget, now: float
              ) -> tuple[RobotPath, int]:
        """One robot's path and its number of failed legs."""
        if not target.active or target.current is None:
            return RobotPath(robot, PATH_IDLE, _NO_POINTS, planned_at=now), 0
        first = self._planner.plan(xy, target.current)
        if not first.found:
            return RobotPath(robot, PATH_FAILED, _NO_POINTS, planned_at=now), 1
        if target.stop_at_current or target.next is None:
            return RobotPath(robot, PATH_OK, first.points, target.stop_at_current, now), 0
        second = self._planner.plan(first.points[-1], target.next)
        if not second.found:
            return RobotPath(robot, PATH_OK, first.points, True, now), 1
        points = np.concatenate([first.points, second.points[1:]])
        points.flags.writeable = False
        return RobotPath(robot, PATH_OK, points, True, now), 0
