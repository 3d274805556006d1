"""Scheduled disturbances: blockages re-route the lanes and the planner, a breakdown hands a
robot's tasks to the others, an outage freezes what robots know of each other."""

import dataclasses
import pathlib

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from mrta_drake import load_scenario, simulate
from mrta_drake.allocation import GreedyAllocator
from mrta_drake.allocation.task_allocator import TaskAllocator
from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.control.safety_rows import ROBOT
from mrta_drake.navigation.costmap import MAX_NON_OBSTACLE, Costmap
from mrta_drake.navigation.grid_planner import GridPlanner
from mrta_drake.navigation.planner_service import PlannerService
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.waypoint_generator import WaypointGenerator
from mrta_drake.payloads import (
    DROPOFF,
    PATH_FAILED,
    PATH_IDLE,
    PATH_OK,
    PICKUP,
    Blockage,
    Breakdown,
    Disturbances,
    FleetPaths,
    FleetPlan,
    Outage,
    QueueState,
    RobotMode,
    RobotPath,
    RobotPlan,
    RobotProgress,
    RoomQueue,
    Stop,
    Visit,
    WaypointTarget,
    frozen_array,
)
from mrta_drake.results.report import format_summary
from mrta_drake.scenario.schema import (
    BlockageConfig,
    DisturbancesConfig,
    TaskBatch,
    TaskConfig,
)
from mrta_drake.stack.disturbance_schedule import DisturbanceSchedule
from mrta_drake.stack.meshcat_overlay import MeshcatOverlay
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.plant import load_floor_plan_of, resolve_locations

ROOT = pathlib.Path(__file__).resolve().parents[2]
HOSPITAL = ROOT / "scenarios/hospital_6_robots.yaml"
# Cross corridor 2, wall to wall, halfway between the east and the west corridor.
CROSS_2 = (-1.0, 1.0, -16.0, -13.1)
# The east corridor between cross corridor 2 and room 2: no lane is left into room 2.
EAST = (3.5, 6.5, -18.2, -16.6)


@pytest.fixture(scope="module")
def hospital():
    scenario = load_scenario(HOSPITAL)
    floor_plan = load_floor_plan_of(scenario)
    scenario = resolve_locations(scenario, floor_plan)
    return scenario, floor_plan, Roadways(scenario.roadways, scenario.locations)


def _crosses(points, box) -> bool:
    """Whether the polyline ``points`` touches ``box``, sampled every 5 cm."""
    points = np.asarray(points, dtype=float)
    for a, b in zip(points[:-1], points[1:], strict=True):
        steps = max(2, int(np.linalg.norm(b - a) / 0.05) + 1)
        samples = a + np.linspace(0, 1, steps)[:, None] * (b - a)
        if Blockage("b", box, 0.0).contains(samples).any():
            return True
    return False


def _run(diagram, times, read):
    """``read(context)`` after advancing to each of ``times``."""
    simulator = Simulator(diagram)
    simulator.Initialize()
    values = []
    for t in times:
        simulator.AdvanceTo(t)
        values.append(read(simulator.get_context()))
    return values


# --- Blockages -------------------------------------------------------------------------------


def test_costmap_with_a_box_added_equals_a_costmap_built_with_it():
    walls = Obstacles(boxes=(Box("south", (4.0, 0.05), (8.0, 0.1)),
                             Box("split", (4.0, 1.4), (0.1, 2.8))))
    bounds = (0.0, 8.0, 0.0, 4.0)
    blocked = Obstacles(boxes=(Box("closed", (6.0, 2.0), (1.0, 0.6)),
                               Box("edge", (0.3, 3.8), (0.6, 0.4))))
    incremental = Costmap.from_obstacles(walls, bounds).with_obstacles(blocked)
    rebuilt = Costmap.from_obstacles(walls.added(blocked.boxes), bounds)
    np.testing.assert_array_equal(incremental.cost, rebuilt.cost)
    np.testing.assert_array_equal(incremental.grid.occupied, rebuilt.grid.occupied)
    assert not incremental.is_traversable([6.0, 2.0]) and incremental.is_traversable([6.0, 3.3])
    # A soft region: its cells cost at least MAX_NON_OBSTACLE, nothing else changes.
    soft = incremental.with_obstacles(Obstacles(cylinders=(Cylinder("r", (2.0, 2.0), 0.5),)),
                                      MAX_NON_OBSTACLE)
    inside = np.linalg.norm(soft.grid.cell_to_world(*np.indices(soft.shape)) - [2.0, 2.0],
                            axis=-1) <= 0.5
    np.testing.assert_array_equal(soft.cost, np.where(inside, np.maximum(
        incremental.cost, MAX_NON_OBSTACLE), incremental.cost))
    np.testing.assert_array_equal(soft.grid.occupied, incremental.grid.occupied)


def test_closed_lanes_route_legs_around_a_blockage_or_leave_none(hospital):
    _, _, roadways = hospital
    open_leg = roadways.leg(1, 4)  # room 1 (east) to room 4 (west), through cross corridor 2
    assert _crosses(open_leg, CROSS_2)
    closed = roadways.closed([CROSS_2])
    detour = closed.leg(1, 4)
    assert not _crosses(detour, CROSS_2)
    np.testing.assert_array_equal(detour[[0, -1]], open_leg[[0, -1]])
    assert roadways.closed([CROSS_2]) is closed and roadways.closed([]) is roadways
    np.testing.assert_array_equal(roadways.leg(1, 4), open_leg)  # the open lanes are unchanged
    # Nothing leads into or out of room 2 with the east corridor blocked above it.
    east = roadways.closed([EAST])
    assert east.leg(1, 2) is None and east.leg(2, 1) is None
    assert east.route_from_point([4.45, -10.0], 2) is None


@pytest.fixture(scope="module")
def planner(hospital):
    _, floor_plan, _ = hospital
    return GridPlanner(Costmap.from_obstacles(floor_plan.obstacles, floor_plan.bounds))


def _paths(planner, starts, goals, schedule, times):
    """The planner service's paths at ``times`` for robots standing at ``starts`` (v = 0)
    driving to ``goals`` (None: nothing to do), under the ``schedule``."""
    robots = tuple(f"r{k}" for k in range(len(starts)))
    builder = DiagramBuilder()
    service = builder.AddSystem(PlannerService(planner, robots, replan_rate_hz=2.0,
                                               target_check_rate_hz=10.0))
    states = builder.AddSystem(ConstantVectorSource(
        np.array([[*xy, 0.0, 0.0] for xy in starts]).ravel()))
    schedule = builder.AddSystem(schedule)
    builder.Connect(states.get_output_port(), service.GetInputPort("robot_state"))
    builder.Connect(states.get_output_port(), schedule.GetInputPort("robot_state"))
    builder.Connect(schedule.GetOutputPort("disturbances"),
                    service.GetInputPort("disturbances"))
    for robot, goal in zip(robots, goals, strict=True):
        target = ConstantValueSource(AbstractValue.Make(
            WaypointTarget(robot, goal is not None, goal, None, True)))
        builder.Connect(builder.AddSystem(target).get_output_port(),
                        service.get_target_input_port(robot))
    return _run(builder.Build(), times, lambda context: (
        service.GetOutputPort("paths").Eval(service.GetMyContextFromRoot(context))))


def test_planner_paths_go_around_a_blockage_only_while_it_is_in_force(planner):
    before, during, after = _paths(
        planner, [(3.0, -14.5), (0.0, -14.5)], [(-3.0, -14.5)] * 2,
        DisturbanceSchedule(["r0", "r1"], [Blockage("cross_2", CROSS_2, 1.0, 3.0)]),
        (0.5, 1.5, 3.5))
    assert [p.status for p in before.paths] == [PATH_OK, PATH_OK]
    assert _crosses(before.paths[0].points, CROSS_2) and before.failures == 0
    # Re-planned at once (1.1 s): around through another cross corridor; the robot inside
    # the closed box has no path until it opens.
    assert during.paths[0].status == PATH_OK and during.paths[0].planned_at == pytest.approx(1.1)
    assert not _crosses(during.paths[0].points, CROSS_2)
    length = np.linalg.norm(np.diff(during.paths[0].points, axis=0), axis=1).sum()
    assert length > 15.0
    assert during.paths[1].status == PATH_FAILED and during.failures >= 1
    assert [p.status for p in after.paths] == [PATH_OK, PATH_OK]
    assert _crosses(after.paths[0].points, CROSS_2)
    np.testing.assert_array_equal(after.paths[0].points, before.paths[0].points)


def test_planner_paths_pass_a_broken_down_robot_at_rest(planner):
    # r0 drives north up the east corridor's northbound lane; r1 stands in it, broken down
    # from 1 s on.
    before, during = _paths(planner, [(5.4, -20.0), (5.4, -17.0)], [(5.4, -14.0), None],
                            DisturbanceSchedule(["r0", "r1"], breakdowns=[Breakdown(1, 1.0)]),
                            (0.5, 1.5))

    def closest(paths):
        return np.linalg.norm(paths.paths[0].points - [5.4, -17.0], axis=1).min()

    assert closest(before) < 0.1 and before.paths[1].status == PATH_IDLE
    assert during.paths[0].status == PATH_OK and closest(during) > 0.7


def _generator(roadways, location, blockage, xy):
    """A waypoint generator for one robot standing at ``xy`` (its start location room 1,
    which it holds), asked to go to ``location``, with ``blockage`` scheduled."""
    builder = DiagramBuilder()
    generator = builder.AddSystem(WaypointGenerator(["r"], 0, roadways, start_location=1,
                                                    rate_hz=10.0))
    state = builder.AddSystem(ConstantVectorSource(np.array([*xy, 0.0, 0.0])))
    plan = FleetPlan((RobotPlan("r", (Stop("go", location),)),), 1)
    queues = QueueState(tuple(RoomQueue(room, "r" if room == 1 else None)
                              for room in roadways.location_ids))
    schedule = builder.AddSystem(DisturbanceSchedule(["r"], [blockage]))
    sources = {"plan": builder.AddSystem(ConstantValueSource(AbstractValue.Make(plan))),
               "queue_state": builder.AddSystem(ConstantValueSource(AbstractValue.Make(queues))),
               "robot_state": state, "disturbances": schedule}
    for port, source in sources.items():
        builder.Connect(source.get_output_port(0), generator.GetInputPort(port))
    builder.Connect(state.get_output_port(), schedule.GetInputPort("robot_state"))
    diagram = builder.Build()

    def read(context):
        own = generator.GetMyContextFromRoot(context)
        return (own.get_abstract_state(0).get_value(),
                generator.GetOutputPort("target").Eval(own),
                generator.GetOutputPort("progress").Eval(own))

    return diagram, read


def test_a_robot_driving_through_a_closing_corridor_is_rerouted_and_back(hospital):
    _, _, roadways = hospital
    point = roadways.place(1).point
    diagram, read = _generator(roadways, 4, Blockage("cross_2", CROSS_2, 1.0, 2.0), point)
    (before, _, _), (during, _, progress_during), (after, target, progress) = _run(
        diagram, (0.5, 1.5, 2.5), read)
    assert before.phase == RobotMode.DRIVE and _crosses(before.route, CROSS_2)
    assert during.phase == RobotMode.DRIVE and not _crosses(during.route, CROSS_2)
    assert during.route[-1] == before.route[-1]  # still to room 4's queue
    assert after.route[after.index:] == before.route[before.index:] and target.active
    first, back = progress.detours
    assert progress_during.detours == (first,)
    assert (first.time, first.blockages, first.found) == (pytest.approx(1.1), ("cross_2",), True)
    assert (back.time, back.blockages, back.found) == (pytest.approx(2.1), ("cross_2",), True)


def test_a_robot_with_no_lane_left_waits_until_the_blockage_ends(hospital):
    _, _, roadways = hospital
    diagram, read = _generator(roadways, 2, Blockage("east", EAST, 1.0, 2.0),
                               roadways.place(1).point)
    (before, _, _), (during, waiting, progress), (after, target, _) = _run(
        diagram, (0.5, 1.5, 2.5), read)
    assert before.phase == RobotMode.DRIVE and _crosses(before.route, EAST)
    assert during.phase == RobotMode.WAIT and not waiting.active
    assert [(d.blockages, d.found) for d in progress.detours] == [(("east",), False)]
    assert after.phase == RobotMode.DRIVE and target.active
    assert after.route[after.index:] == before.route[before.index:]


def test_blockages_show_in_meshcat_only_while_in_force(hospital):
    scenario, _, _ = hospital
    scenario = dataclasses.replace(scenario, disturbances=DisturbancesConfig(
        blockages=[BlockageConfig("cross_2", list(CROSS_2), 1.0, 2.0)]))
    meshcat = Meshcat()
    builder = DiagramBuilder()
    overlay = builder.AddSystem(MeshcatOverlay(meshcat, scenario, rate_hz=10.0))
    schedule = builder.AddSystem(DisturbanceSchedule([r.name for r in scenario.robots],
                                                     [Blockage("cross_2", CROSS_2, 1.0, 2.0)]))
    builder.Connect(builder.AddSystem(ConstantVectorSource(np.zeros(24))).get_output_port(),
                    schedule.GetInputPort("robot_state"))
    builder.Connect(schedule.GetOutputPort("disturbances"),
                    overlay.GetInputPort("disturbances"))
    for port, value in (("paths", FleetPaths(())), ("queue_state", QueueState())):
        builder.Connect(builder.AddSystem(ConstantValueSource(AbstractValue.Make(value)))
                        .get_output_port(), overlay.GetInputPort(port))
    path = "/drake/traffic/blockages/cross_2"
    shown = _run(builder.Build(), (0.55, 1.55, 2.55), lambda context: meshcat._GetPackedProperty(
        path, "visible").endswith(b"\xc3"))  # msgpack true
    assert meshcat.HasPath(path) and shown == [False, True, False]


# --- Breakdowns ------------------------------------------------------------------------------


def test_a_broken_down_robot_stops_and_another_does_its_task(tmp_path):
    # robot2 waits in room 5's parking spot and gets the task (pickup at room 5); it breaks
    # down after 1 s, and robot1 drives from the lobby to do it instead.
    path = tmp_path / "breakdown.yaml"
    path.write_text(f"""
world: {{floor_plan: {ROOT}/models/hospital/floor_plan.yaml}}
locations: {ROOT}/models/hospital/navigation.yaml
roadways: {ROOT}/models/hospital/navigation.yaml
robots:
  - {{name: robot1, start: [0.0, 2.2, -1.5708], start_location: 0}}
  - {{name: robot2, start: [-7.9, -5.9, -1.5708]}}
tasks:
  stream: [{{arrival: 0, tasks: [{{pickup: 5, dropoff: 4, deadline: 300}}]}}]
disturbances:
  breakdowns: [{{robot: robot2, start: 1.0}}]
duration: 70
""")
    result = simulate(load_scenario(path))
    allocations = [e["event"] for e in result.events if e["type"] == "allocation"]
    assert allocations[0]["assignment"] == (("robot1", ()), ("robot2", (0,)))
    removal = allocations[1]
    assert removal["time"] == 2.0 and removal["removed"] == ("robot2",)
    assert removal["assignment"] == (("robot1", (0,)),) and removal["reassigned"] == (0,)
    task = result.summary["tasks"]["per_task"][0]
    assert task["robot"] == "robot1" and task["status"] == "on_time"
    starts = [e for e in result.events if e["type"] == "disturbance"]
    assert [(e["phase"], e["kind"], e["robot"], e["at"]) for e in starts] == [
        ("start", "breakdown", "robot2", 1.0)]
    assert result.summary["disturbances"] == [{
        "kind": "breakdown", "robot": "robot2", "start": 1.0, "end": None, "removed_at": 2.0,
        "tasks_reassigned": [0], "tasks_failed": []}]
    assert ("breakdown robot2 from 1 s: out of the fleet at 2 s, tasks reassigned [0], "
            "failed []") in format_summary(result.summary)
    # It braked to a stop within a second and stayed there.
    after = result.robot_states[result.times >= 2.5, 1]
    assert np.abs(after[:, 3]).max() == 0.0
    assert np.ptp(after[:, :2], axis=0).max() == 0.0


class _Progress(LeafSystem):
    """Reports ``before`` until ``switch`` s, then ``after`` (a robot's progress)."""

    def __init__(self, before: RobotProgress, after: RobotProgress, switch: float):
        super().__init__()
        self.DeclareAbstractOutputPort(
            "progress", lambda: AbstractValue.Make(before),
            lambda context, out: out.set_value(before if context.get_time() < switch
                                               else after))


def test_items_on_a_broken_down_robot_are_lost_and_the_rest_reassigned():
    travel = 10 * np.abs(np.subtract.outer(np.arange(3), np.arange(3)))
    stream = (TaskBatch(0.0, (TaskConfig(1, 2, 500.0), TaskConfig(0, 2, 500.0))),)
    builder = DiagramBuilder()
    allocator = builder.AddSystem(TaskAllocator(stream, ["a", "b"], [1, 2], [2, 2], travel,
                                                GreedyAllocator(), rate_hz=1.0))
    # Robot a picks task 0 up at 1.5 s and drives to drop it; it breaks down at 2.5 s.
    picked = RobotProgress("a", (Visit("t0/pickup", 1, 1.5, 0, PICKUP),), 1,
                           Stop("t0/dropoff", 2, DROPOFF, 0))
    for k, progress in enumerate((_Progress(RobotProgress("a", last_location=1), picked, 1.5),
                                  _Progress(RobotProgress("b", last_location=2),
                                            RobotProgress("b", last_location=2), 0.0))):
        builder.Connect(builder.AddSystem(progress).get_output_port(),
                        allocator.get_progress_input_port(k))
    schedule = builder.AddSystem(DisturbanceSchedule(["a", "b"], breakdowns=[Breakdown(0, 2.5)]))
    builder.Connect(builder.AddSystem(ConstantVectorSource(np.zeros(8))).get_output_port(),
                    schedule.GetInputPort("robot_state"))
    builder.Connect(schedule.GetOutputPort("disturbances"),
                    allocator.GetInputPort("disturbances"))
    first, second = _run(builder.Build(), (0.5, 3.5), lambda context: (
        allocator.GetOutputPort("plan").Eval(allocator.GetMyContextFromRoot(context)),
        allocator.GetOutputPort("events").Eval(allocator.GetMyContextFromRoot(context))))
    assert {stop.task for stop in first[0].plans[0].stops} == {0, 1}
    plan, events = second
    assert len(events) == 2 and plan.plans[0].stops == ()
    event = events[-1]
    assert (event.time, event.removed, event.lost_tasks, event.reassigned) == (
        3.0, ("a",), (0,), (1,))
    assert [stop.key for stop in plan.plans[1].stops] == ["t1/pickup", "t1/dropoff"]


# --- Outages ---------------------------------------------------------------------------------


class _Moving(LeafSystem):
    """Robot states [x, y, 0, 1] with x = x0 + t: robots driving east at 1 m/s."""

    def __init__(self, x0, y):
        super().__init__()
        self._x0, self._y = np.asarray(x0, float), np.asarray(y, float)
        self.DeclareVectorOutputPort("state", BasicVector(4 * len(x0)), self._calc)

    def _calc(self, context, output):
        n = len(self._x0)
        states = np.column_stack([self._x0 + context.get_time(), self._y, np.zeros(n),
                                  np.ones(n)])
        output.SetFromVector(states.ravel())


def test_an_outage_freezes_the_states_robots_exchange():
    builder = DiagramBuilder()
    moving = builder.AddSystem(_Moving([0.0, 0.0, 0.0], [0.0, 1.0, 2.0]))
    schedule = builder.AddSystem(DisturbanceSchedule(["r0", "r1", "r2"],
                                                     outages=[(1, 1.0, 3.0), (2, 2.0, 4.0)]))
    builder.Connect(moving.get_output_port(), schedule.GetInputPort("robot_state"))
    seen = _run(builder.Build(), (0.5, 2.5, 3.5, 4.5), lambda context: (
        schedule.GetOutputPort("disturbances").Eval(schedule.GetMyContextFromRoot(context))))
    assert [d.cut_off for d in seen] == [(), (1, 2), (2,), ()]
    live = np.array([[2.5, 0.0, 0.0, 1.0], [2.5, 1.0, 0.0, 1.0], [2.5, 2.0, 0.0, 1.0]])
    d = seen[1]
    # The others know robot 1 as of 1 s and robot 2 as of 2 s; robot 1 knows robot 0 as of
    # 1 s and robot 2 as of 1 s (when it was cut off first); robot 2 knows robot 1 as of 1 s.
    np.testing.assert_array_equal(d.seen_by(live)[:, 0], [2.5, 1.0, 2.0])
    np.testing.assert_array_equal(d.seen_by(live, 1)[:, 0], [1.0, 2.5, 1.0])
    np.testing.assert_array_equal(d.seen_by(live, 2)[:, 0], [2.0, 1.0, 2.5])


def test_during_an_outage_controllers_see_the_frozen_state():
    controller = ClusterCbfController(["a", "b", "c"], rate_hz=20.0)
    states = np.array([[0.0, 0.0, 0.0, 0.5], [1.5, 0.0, np.pi, 0.5], [10.0, 0.0, 0.0, 0.0]])
    paths = FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array([s[:2], s[:2] + [3.0, 0.0]]),
                                       True) for name, s in zip("abc", states, strict=True)))
    # b was at (3, 0) when it was cut off; a was at (-2, 0) then.
    snapshot = states.copy()
    snapshot[0, 0], snapshot[1, 0] = -2.0, 3.0
    outage = Disturbances(outages=(Outage(1, 0.0, 5.0, frozen_array(snapshot)),))
    normal = controller.plan(states, paths)
    assert normal.clusters[0] == (0, 1)
    plan = controller.plan(states, paths, disturbances=outage)
    assert plan.clusters == ((0,), (1,), (2,))
    for problem, own, other in ((plan.problems[0], states[0], snapshot[1]),
                                (plan.problems[1], states[1], snapshot[0])):
        rows = problem.rows.kind == ROBOT
        assert rows.sum() == 1
        expected = np.sum((own[:2] - other[:2]) ** 2) - controller.params.safety_distances.robot**2
        assert problem.rows.h[rows][0] == pytest.approx(expected)


def test_broken_down_robots_are_in_no_qp_and_get_zero_commands():
    controller = ClusterCbfController(["a", "b"], rate_hz=20.0)
    states = np.array([[0.0, 0.0, 0.0, 0.5], [1.5, 0.0, np.pi, 0.5]])
    paths = FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array([s[:2], s[:2] + [3.0, 0.0]]),
                                       True) for name, s in zip("ab", states, strict=True)))
    plan = controller.plan(states, paths,
                           disturbances=Disturbances(breakdowns=(Breakdown(1, 0.0),)))
    assert [p.members for p in plan.problems] == [(0,)]
    assert (plan.problems[0].rows.kind == ROBOT).sum() == 1  # keeps clear of the broken one


def test_example_scenario_has_every_kind_of_disturbance():
    scenario = load_scenario(ROOT / "scenarios/hospital_disturbances.yaml")
    d = scenario.disturbances
    assert len(scenario.robots) == 6 and d.blockages and d.breakdowns and d.outages
