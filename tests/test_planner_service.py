"""PlannerService in a Simulator: fixed robot states, fixed or switching targets."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue, Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from mrta_drake.costmap import Costmap
from mrta_drake.grid_planner import GridPlanner
from mrta_drake.obstacles import Box, Obstacles
from mrta_drake.payloads import PATH_FAILED, PATH_IDLE, PATH_OK, FleetPaths, WaypointTarget
from mrta_drake.systems.planner_service import PlannerService, PlannerServiceParams

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


def build(planner, sources: dict, replan_rate=2.0):
    builder = DiagramBuilder()
    service = builder.AddSystem(PlannerService(planner, ROBOTS, replan_rate=replan_rate))
    states = builder.AddSystem(ConstantVectorSource(np.array(STATES)))
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
    simulator, paths = build(planner, sources, replan_rate=1.0)
    simulator.AdvanceTo(0.25)
    assert paths().paths[0].planned_at == 0.0
    simulator.AdvanceTo(0.35)
    now = paths()
    r0, r1 = now.paths[0], now.paths[1]
    assert r0.planned_at == pytest.approx(0.3) and r1.planned_at == 0.0  # only r0 re-planned
    np.testing.assert_allclose(r0.points[-1], (1.0, 3.0))
    assert r0.stop_at_end
    assert now.failures == 0 and all(p.status == PATH_OK for p in now.paths)


def test_from_obstacles_builds_the_costmap_and_planner():
    service = PlannerService.from_obstacles(WALLS, BOUNDS, ROBOTS, PlannerServiceParams())
    assert service.robots == ROBOTS
    assert service.planner.costmap.shape == (80, 160)
    assert service.GetInputPort("robot_state").size() == 12
    assert service.get_target_input_port("r2").get_name() == "target_r2"
    assert service.GetOutputPort("paths").get_name() == "paths"
