"""One planner block serving every robot, like the single shared Nav2 planner server."""

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.costmap import Costmap, CostmapParams
from mrta_drake.grid_planner import GridPlanner, PlannerParams
from mrta_drake.obstacles import Obstacles
from mrta_drake.payloads import (
    PATH_FAILED,
    PATH_IDLE,
    PATH_OK,
    ROBOT_STATE_SIZE,
    FleetPaths,
    RobotPath,
    WaypointTarget,
    frozen_array,
)


@dataclass(frozen=True)
class PlannerServiceParams:
    """Costmap and planner parameters of the block, and how often (Hz) it looks for changed
    targets between its periodic re-plans."""

    costmap: CostmapParams = field(default_factory=CostmapParams)
    planner: PlannerParams = field(default_factory=PlannerParams)
    target_check_rate: float = 10.0


@dataclass(frozen=True)
class _ServiceState:
    """The block's abstract state: the paths it outputs, the targets they were planned
    for, and the time (s) of the next periodic re-plan."""

    paths: FleetPaths
    targets: tuple[WaypointTarget | None, ...]
    next_replan: float

    def __deepcopy__(self, memo):
        # Everything in here is immutable, so Drake's per-update copy can share it.
        return self


class PlannerService(LeafSystem):
    """Plans a path for every robot with one shared ``GridPlanner``.

    Inputs: ``robot_state`` (vector, 4N: x, y, theta, v per robot, world frame) and
    ``target_<robot>`` (abstract ``WaypointTarget``), one per robot in ``robots`` order; all
    must be connected. Output: ``paths`` (abstract ``FleetPaths``), from the state.

    Every ``1 / target_check_rate`` s an unrestricted update re-plans the robots whose target
    changed since their last plan, and every ``1 / replan_rate`` s (at the first check tick
    at or after that time) all robots. A robot with an active target gets a path from its
    position through ``current`` and, unless it must stop there, on to ``next``. If the leg
    to ``current`` has no path the robot's path is ``failed`` (it waits; re-planned at the
    next periodic re-plan); if only the leg on to ``next`` fails the path ends at
    ``current``. Each failed leg adds one to ``FleetPaths.failures``. A path ends with a stop
    (``stop_at_end``) at ``next``, or at ``current`` when the target says so.
    """

    def __init__(self, planner: GridPlanner, robots: Sequence[str], replan_rate: float = 2.0,
                 target_check_rate: float = 10.0):
        super().__init__()
        if replan_rate <= 0.0 or target_check_rate <= 0.0:
            raise ValueError("replan_rate and target_check_rate must be positive")
        self._planner = planner
        self._robots = tuple(robots)
        self._replan_period = 1.0 / replan_rate
        n = len(self._robots)
        initial = _ServiceState(
            FleetPaths(tuple(RobotPath(robot) for robot in self._robots)), (None,) * n, 0.0)
        self._state_index = self.DeclareAbstractState(Value[object](initial))
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * n))
        self._targets = [
            self.DeclareAbstractInputPort(f"target_{robot}", Value[object](WaypointTarget(robot)))
            for robot in self._robots
        ]
        self.DeclareAbstractOutputPort(
            "paths",
            lambda: Value[object](initial.paths),
            self._calc_paths,
            prerequisites_of_calc={self.abstract_state_ticket(self._state_index)},
        )
        self.DeclareInitializationUnrestrictedUpdateEvent(self._update)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / target_check_rate, 0.0, self._update)

    @classmethod
    def from_obstacles(cls, obstacles: Obstacles, bounds, robots: Sequence[str],
                       params: PlannerServiceParams = PlannerServiceParams(),
                       replan_rate: float = 2.0) -> "PlannerService":
        """A block planning over ``obstacles`` rasterized on ``bounds`` = (x_min, x_max,
        y_min, y_max) (m) at the costmap's default resolution."""
        costmap = Costmap.from_obstacles(obstacles, bounds, params.costmap)
        return cls(GridPlanner(costmap, params.planner), robots, replan_rate,
                   params.target_check_rate)

    @property
    def planner(self) -> GridPlanner:
        return self._planner

    @property
    def robots(self) -> tuple[str, ...]:
        return self._robots

    def get_target_input_port(self, robot: str):
        return self._targets[self._robots.index(robot)]

    def _calc_paths(self, context, output):
        output.set_value(context.get_abstract_state(self._state_index).get_value().paths)

    def _update(self, context, state):
        old = context.get_abstract_state(self._state_index).get_value()
        now = context.get_time()
        targets = tuple(port.Eval(context) for port in self._targets)
        replan_all = now >= old.next_replan - 1e-9
        due = [k for k in range(len(self._robots))
               if replan_all or targets[k] != old.targets[k]]
        if not due:
            return EventStatus.DidNothing()
        robot_state = self._robot_state.Eval(context)
        paths = list(old.paths.paths)
        failures = old.paths.failures
        for k in due:
            xy = robot_state[ROBOT_STATE_SIZE * k:ROBOT_STATE_SIZE * k + 2]
            paths[k], failed = self._plan(self._robots[k], xy, targets[k], now)
            failures += failed
        next_replan = old.next_replan
        if replan_all:
            # Keep the period's phase, but never fall behind the clock.
            next_replan = max(next_replan + self._replan_period, now + 0.5 * self._replan_period)
        state.get_mutable_abstract_state(self._state_index).set_value(
            _ServiceState(FleetPaths(tuple(paths), failures), targets, next_replan))
        return EventStatus.Succeeded()

    def _plan(self, robot: str, xy: np.ndarray, target: WaypointTarget, now: float
              ) -> tuple[RobotPath, int]:
        """One robot's path and its number of failed legs."""
        if not target.active or target.current is None:
            return RobotPath(robot, PATH_IDLE, planned_at=now), 0
        first = self._planner.plan(xy, target.current)
        if not first.found:
            return RobotPath(robot, PATH_FAILED, planned_at=now), 1
        if target.stop_at_current or target.next is None:
            return RobotPath(robot, PATH_OK, first.points, target.stop_at_current, now), 0
        second = self._planner.plan(first.points[-1], target.next)
        if not second.found:
            return RobotPath(robot, PATH_OK, first.points, True, now), 1
        points = frozen_array(np.vstack([first.points, second.points[1:]]))
        return RobotPath(robot, PATH_OK, points, True, now), 0
