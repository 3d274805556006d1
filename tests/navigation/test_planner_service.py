"""PlannerService in a Simulator: fixed robot states, fixed or switching targets; and in
closed loop with the cluster CBF controller and unicycle robots."""

import pathlib

import numpy as np
import pytest
from pydrake.common.value import AbstractValue, Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource, LogVectorOutput

from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.navigation.costmap import Costmap
from mrta_drake.navigation.grid_planner import GridPlanner
from mrta_drake.navigation.planner_service import PlannerService, PlannerServiceParams
from mrta_drake.payloads import (
    PATH_FAILED,
    PATH_IDLE,
    PATH_OK,
    FleetPaths,
    Relocations,
    WaypointTarget,
)
from mrta_drake.robots.unicycle_robots import UnicycleRobots
from mrta_drake.world.obstacles import Box, Obstacles

FLOOR_PLAN = pathlib.Path(__file__).resolve().parents[2] / "models/hospital/floor_plan.yaml"

BOUNDS = (0.0, 8.0, 0.0, 4.0)
# An 8 m x 4 m walled hall split by a wall at x = 4 with a 1.2 m gap at its north end,
# and a crate at (6, 1).
WALLS = Obstacles(boxes=(
    Box("south", (4.0, 0.05), (8.0, 0.1)), Box("north", (4.0, 3.95), (8.0, 0.1)),
    Box("west", (0.05, 2.0), (0.1, 4.0)), Box("east", (7.95, 2.0), (0.1, 4.0)),
    Box("split", (4.0, 1.4), (0.1, 2.8)), Box("crate", (6.0, 1.0), (0.6, 0.6)),
))
ROBOTS = ("r0", "r1", "r2")
STATES = [1.0, 1.0, 0.0, 0.0,  # r0, west half
          6.0, 3.0, 0.0, 0.0,  # r1, east half
          2.0, 3.0, 0.0, 0.0]  # r2, west half


@pytest.fixture(scope="module")
def planner() -> GridPlanner:
    return GridPlanner(Costmap.from_obstacles(WALLS, BOUNDS))


class SwitchingTarget(LeafSystem):
    """Outputs ``before`` until ``switch_time`` (s), then ``after``."""

    def __init__(self, before: WaypointTarget, after: WaypointTarget, switch_time: float):
        super().__init__()
        self.DeclareAbstractOutputPort(
            "target", lambda: Value[object](before),
            lambda context, out: out.set_value(before if context.get_time() < switch_time
                                               else after))


def build(planner, sources: dict, replan_rate_hz=2.0, states=STATES, cost_resting_robots=True):
    builder = DiagramBuilder()
    service = builder.AddSystem(PlannerService(planner, ROBOTS, replan_rate_hz=replan_rate_hz,
                                               target_check_rate_hz=10.0,
                                               cost_resting_robots=cost_resting_robots))
    states = builder.AddSystem(ConstantVectorSource(np.array(states)))
    builder.Connect(states.get_output_port(), service.GetInputPort("robot_state"))
    for robot in ROBOTS:
        source = sources[robot]
        if isinstance(source, WaypointTarget):
            source = ConstantValueSource(AbstractValue.Make(source))
        builder.Connect(builder.AddSystem(source).get_output_port(),
                        service.get_target_input_port(robot))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    return simulator, lambda: service.GetOutputPort("paths").Eval(
        service.GetMyContextFromRoot(context))


def test_paths_through_current_and_next_and_failures_counted(planner):
    sources = {
        # Through the gap in the split wall, then on to a point past the crate.
        "r0": WaypointTarget("r0", True, current=(6.0, 2.5), next=(7.0, 0.5),
                             stop_at_current=False),
        "r1": WaypointTarget("r1", True, current=(6.0, 1.0)),  # inside the crate
        "r2": WaypointTarget("r2"),  # inactive
    }
    simulator, paths = build(planner, sources)
    simulator.Initialize()
    first = paths()
    assert isinstance(first, FleetPaths)
    assert [p.status for p in first.paths] == [PATH_OK, PATH_FAILED, PATH_IDLE]
    assert first.failures == 1
    r0 = first.paths[0]
    np.testing.assert_allclose(r0.points[0], (1.0, 1.0))
    np.testing.assert_allclose(r0.points[-1], (7.0, 0.5))
    assert r0.stop_at_end
    assert np.min(np.linalg.norm(r0.points - (6.0, 2.5), axis=1)) < 1e-9  # passes current
    assert np.all(r0.points[:, 1][np.abs(r0.points[:, 0] - 4.0) < 0.3] > 2.8)  # via the gap
    assert np.all(planner.costmap.is_traversable(r0.points[1:]))
    assert first.paths[1].points.shape == (0, 2)

    # Retried at each 2 Hz re-plan (t = 0.5, 1.0), each attempt counted; never raises.
    simulator.AdvanceTo(1.05)
    later = paths()
    assert later.failures == 3
    assert later.paths[1].status == PATH_FAILED
    assert later.paths[0].planned_at == pytest.approx(1.0)


def test_a_changed_target_is_planned_at_the_next_check_tick(planner):
    before = WaypointTarget("r0", True, current=(2.0, 1.0))
    after = WaypointTarget("r0", True, current=(1.0, 3.0), stop_at_current=True)
    sources = {"r0": SwitchingTarget(before, after, 0.22),
               "r1": WaypointTarget("r1", True, current=(7.0, 3.0)),
               "r2": WaypointTarget("r2", True, current=(6.5, 2.0))}  # through the gap
    simulator, paths = build(planner, sources, replan_rate_hz=1.0)
    simulator.AdvanceTo(0.25)
    assert paths().paths[0].planned_at == 0.0
    simulator.AdvanceTo(0.35)
    now = paths()
    r0, r1 = now.paths[0], now.paths[1]
    assert r0.planned_at == pytest.approx(0.3) and r1.planned_at == 0.0  # only r0 re-planned
    np.testing.assert_allclose(r0.points[-1], (1.0, 3.0))
    assert r0.stop_at_end
    assert now.failures == 0 and all(p.status == PATH_OK for p in now.paths)


def test_paths_go_around_robots_standing_in_the_way(planner):
    # Regression (robots standing nose to nose along a wall stayed there, their paths
    # running through each other): r0 and r1 stand 1 m apart in the west half, each to
    # drive on past the other.
    def paths_with(r1_speed, r1_active, cost_resting_robots=True):
        states = [1.5, 2.0, 0.0, 0.0, 2.5, 2.0, np.pi, r1_speed, 6.0, 3.0, 0.0, 0.0]
        sources = {"r0": WaypointTarget("r0", True, current=(3.4, 2.0)),
                   "r1": WaypointTarget("r1", r1_active,
                                        current=(0.6, 2.0) if r1_active else None),
                   "r2": WaypointTarget("r2")}
        simulator, paths = build(planner, sources, states=states,
                                 cost_resting_robots=cost_resting_robots)
        simulator.AdvanceTo(0.05)
        return paths().paths

    def closest(path, xy):
        return np.linalg.norm(path.points - xy, axis=1).min()

    r0, r1, _ = paths_with(0.0, True)
    assert r0.status == PATH_OK and r1.status == PATH_OK
    assert closest(r0, (2.5, 2.0)) > 0.7 and closest(r1, (1.5, 2.0)) > 0.7
    np.testing.assert_allclose(r1.points[[0, -1]], [(2.5, 2.0), (0.6, 2.0)])
    # A moving robot, or one standing with nothing to do, is no obstacle to paths.
    r0, r1, _ = paths_with(0.5, True)
    assert closest(r0, (2.5, 2.0)) < 0.1 and closest(r1, (1.5, 2.0)) > 0.7
    r0, _, _ = paths_with(0.0, False)
    assert closest(r0, (2.5, 2.0)) < 0.1
    # Switched off (the paper's static map), the standing robots are no obstacle either.
    r0, r1, _ = paths_with(0.0, True, cost_resting_robots=False)
    assert closest(r0, (2.5, 2.0)) < 0.1 and closest(r1, (1.5, 2.0)) < 0.1


class SwitchingState(LeafSystem):
    """Outputs robot state vector ``before`` until ``switch_time`` (s), then ``after``."""

    def __init__(self, before, after, switch_time: float):
        super().__init__()
        self.DeclareVectorOutputPort(
            "state", len(before),
            lambda context, out: out.SetFromVector(before if context.get_time() < switch_time
                                                   else after))


def test_a_relocated_robot_stands_without_failing_until_its_target_changes():
    # Regression (the hotel's lift rides): a robot relocated by a lift ride to another
    # level kept, until its waypoint generator's next tick, the target it had on the level
    # it left; a re-plan in between failed ("goal unreachable") and was counted. Here two
    # rooms with no way between them stand for two levels: r0 jumps at 0.22 s from the west
    # room to the east one (relocation 1), its target moves there at 0.62 s.
    rooms = Obstacles(boxes=(
        Box("south", (4.0, 0.05), (8.0, 0.1)), Box("north", (4.0, 3.95), (8.0, 0.1)),
        Box("west", (0.05, 2.0), (0.1, 4.0)), Box("east", (7.95, 2.0), (0.1, 4.0)),
        Box("split", (4.0, 2.0), (0.4, 4.0))))
    west = WaypointTarget("r0", True, current=(3.0, 3.0))
    east = WaypointTarget("r0", True, current=(7.0, 1.0))
    builder = DiagramBuilder()
    service = builder.AddSystem(PlannerService(
        GridPlanner(Costmap.from_obstacles(rooms, BOUNDS)), ("r0",), replan_rate_hz=2.0,
        target_check_rate_hz=10.0))
    state = builder.AddSystem(SwitchingState([1.0, 1.0, 0.0, 0.0], [5.0, 3.0, 0.0, 0.0], 0.22))
    moved = builder.AddSystem(SwitchingTarget(Relocations((None,)),
                                              Relocations(((1, (5.0, 3.0, 0.0)),)), 0.22))
    target = builder.AddSystem(SwitchingTarget(west, east, 0.62))
    builder.Connect(state.get_output_port(), service.GetInputPort("robot_state"))
    builder.Connect(moved.get_output_port(), service.GetInputPort("relocations"))
    builder.Connect(target.get_output_port(), service.get_target_input_port("r0"))
    simulator = Simulator(builder.Build())
    context = service.GetMyContextFromRoot(simulator.get_mutable_context())

    def path_at(t):
        simulator.AdvanceTo(t)
        paths = service.GetOutputPort("paths").Eval(context)
        return paths.paths[0], paths.failures

    path, failures = path_at(0.25)
    assert path.status == PATH_OK and path.planned_at == 0.0
    # Seen at the next check tick, and again at the periodic re-plan (0.5 s): it stands.
    for t, planned in ((0.35, 0.3), (0.55, 0.5)):
        path, failures = path_at(t)
        assert (path.status, path.planned_at, failures) == (PATH_IDLE, pytest.approx(planned), 0)
    path, failures = path_at(0.75)
    assert path.status == PATH_OK and failures == 0
    np.testing.assert_allclose(path.points[[0, -1]], [(5.0, 3.0), (7.0, 1.0)])


def test_from_obstacles_builds_the_costmap_and_planner():
    service = PlannerService.from_obstacles(WALLS, BOUNDS, ROBOTS, PlannerServiceParams(),
                                            replan_rate_hz=2.0, target_check_rate_hz=10.0)
    assert service.robot_names == ROBOTS
    assert service.planner.costmap.shape == (80, 160)
    assert service.GetInputPort("robot_state").size() == 12
    assert service.get_target_input_port("r2").get_name() == "target_r2"
    assert service.GetOutputPort("paths").get_name() == "paths"


def test_a_column_standing_along_the_hospital_east_wall_gets_moving():
    # Regression, from the six-robot hospital sweep (seed 16, 126 s): in the east corridor
    # (x 3.6 .. 6.4) r0 and r1 stand in a column against the wall, bound north, and r2 nose
    # to nose with r1, bound south to room 2's door. With paths through the standing robots
    # r0 and r1 were still there after 40 s; with paths around them all three get by (r2,
    # in the column's way, yields and backs off north until r0 and r1 are by: ~48 s).
    from mrta_drake.world.floor_plan import load_floor_plan

    obstacles = load_floor_plan(FLOOR_PLAN).obstacles
    names = ("r0", "r1", "r2")
    starts = [[5.83, -20.28, 1.01], [5.81, -19.65, 1.43], [5.83, -18.94, -1.57]]
    north = ((5.4, -15.1), (5.4, -14.0))
    targets = (north, north, ((6.0, -21.85), (5.85, -23.05)))
    builder = DiagramBuilder()
    robots = builder.AddSystem(UnicycleRobots(names, np.array(starts), rate_hz=20.0))
    controller = builder.AddSystem(ClusterCbfController(names, obstacles, rate_hz=20.0))
    service = builder.AddSystem(PlannerService.from_obstacles(
        obstacles, (2.0, 9.0, -26.0, -12.0), names, replan_rate_hz=2.0,
        target_check_rate_hz=10.0))
    builder.Connect(robots.GetOutputPort("state"), controller.GetInputPort("robot_state"))
    builder.Connect(robots.GetOutputPort("state"), service.GetInputPort("robot_state"))
    builder.Connect(service.GetOutputPort("paths"), controller.GetInputPort("paths"))
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    for name, (current, after) in zip(names, targets, strict=True):
        source = builder.AddSystem(ConstantValueSource(AbstractValue.Make(
            WaypointTarget(name, True, current, after, False))))
        builder.Connect(source.get_output_port(), service.get_target_input_port(name))
    log = LogVectorOutput(robots.GetOutputPort("state"), builder, 0.5)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(50.0)
    y = log.FindLog(simulator.get_context()).data().T.reshape(-1, 3, 4)[:, :, 1]
    assert y[:, 0].max() > -16.0 and y[:, 1].max() > -16.0 and y[:, 2].min() < -22.0
