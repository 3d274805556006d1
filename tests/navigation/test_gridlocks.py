"""Gridlocks of waits: robots waiting for rooms and single-file segments held by each other,
found from the room queues' facts (``standstills.waits_for``, ``standstills.gridlocks``) and
broken by the deadlock watchdog (``releases`` orders, step 5 of ``DeadlockWatchdog``)."""

from dataclasses import replace

import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake.allocation.fixed_sequence_allocator import FixedSequenceAllocator
from mrta_drake.errors import InputError
from mrta_drake.navigation.costmap import Costmap
from mrta_drake.navigation.deadlock_watchdog import DeadlockWatchdog, WatchdogParams
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.room_queues import RoomQueues
from mrta_drake.navigation.single_file import Need, SingleFileParams, stop_segments
from mrta_drake.navigation.standstills import gridlocks, waits_for
from mrta_drake.navigation.waypoint_generator import (
    WaypointGenerator,
    WaypointParams,
    WaypointPolicy,
    _Drive,
)
from mrta_drake.payloads import (
    NO_BACK_OFFS,
    BackOff,
    BackOffOrders,
    QueueRequest,
    QueueState,
    RobotMode,
    RoomQueue,
    SegmentHold,
    WaypointTarget,
)
from mrta_drake.results.deadlocks import stalled_waits
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from mrta_drake.world.obstacles import Obstacles
from tests.navigation.test_waypoint_generator import (
    B,
    FakeRobots,
    _Inputs,
    queueing_at_b,
    spur_world,
    stepper,
)

R, H, G = 0, 1, 2  # the room at the corridor's dead end, and two rooms west of it
BOUNDS = (-14.0, 24.0, -4.0, 6.0)


def test_gridlocks_join_stalled_waits_with_the_robots_they_wait_for():
    waits = {"a": {"b"}, "b": {"a"},  # a cycle of two
             "c": {"d"}, "d": {"e"}, "e": {"c"},  # a cycle of three
             "f": {"g"},  # g stands for good, waiting for nothing
             "h": {"a"}}  # waits for the first cycle
    stalled = stalled_waits(waits, set())
    assert gridlocks(waits, stalled) == [("a", "b", "h"), ("c", "d", "e"), ("f", "g")]
    assert gridlocks(waits, stalled_waits(waits, {"g", "e"})) == [("a", "b", "h")]


def test_waits_for_names_the_holders_or_the_robots_first_in_line():
    queues = QueueState((RoomQueue(0, "a", ("b",)),),
                        segments=(SegmentHold(("b",)), SegmentHold()),
                        segment_waiting=("a", "c", "d"))
    requests = (QueueRequest("a", segments=((0, False),)), QueueRequest("b", 0),
                QueueRequest("c", segments=((1, True),)),
                QueueRequest("d", segments=((1, True),)))
    assert waits_for(queues, requests) == {"a": {"b"}, "b": {"a"}, "c": set(), "d": {"c"}}


def _dead_end() -> Roadways:
    """Lanes both ways W2 (-10, 0) - W (0, 0) - J (10, 0) - E (20, 0); J - E is one
    single-file segment (0). Room R's point (20, 2) lies past its dead end, its two queue
    slots on it; rooms H (0, 2) and G (-10, 2) beside the west end."""
    nodes = {"W2": [-10.0, 0.0], "W": [0.0, 0.0], "J": [10.0, 0.0], "E": [20.0, 0.0]}
    pairs = [("W2", "W"), ("W", "J"), ("J", "E")]
    edges = [[a, b] for a, b in pairs] + [[b, a] for a, b in pairs]
    locations = [
        LocationConfig(id=R, name="R", point=[20.0, 2.0], queue=[[18.5, 0.0], [17.0, 0.0]],
                       exit_node="E", approach_node="E"),
        LocationConfig(id=H, name="H", point=[0.0, 2.0], queue=[[1.5, 0.0]],
                       exit_node="W", approach_node="W"),
        LocationConfig(id=G, name="G", point=[-10.0, 2.0], queue=[[-8.5, 0.0]],
                       exit_node="W2", approach_node="W2"),
    ]
    return Roadways(RoadwaysConfig(nodes=nodes, edges=edges, single_file=[["J", "E"]]),
                    locations)


class _Obeying(LeafSystem):
    """The planner's part here: each robot's target (``target_<i>`` in and out), or its
    back-off spot while the watchdog orders one (input ``back_offs``)."""

    def __init__(self, names):
        super().__init__()
        self._names = names
        self._orders = self.DeclareAbstractInputPort("back_offs", Value[object](NO_BACK_OFFS))
        self._targets = [self.DeclareAbstractInputPort(
            f"target_{i}", Value[object](WaypointTarget(name))) for i, name in enumerate(names)]
        for i in range(len(names)):
            self.DeclareAbstractOutputPort(
                f"target_{i}", lambda: Value[object](WaypointTarget("")),
                lambda context, output, i=i: output.set_value(self._target(context, i)))

    def _target(self, context, i: int) -> WaypointTarget:
        order = self._orders.Eval(context).of(self._names[i])
        if order is None:
            return self._targets[i].Eval(context)
        return WaypointTarget(self._names[i], True, order.point, None, True)


def _gridlock_run(starts, routes, until, sees_waits=True):
    """Robots ``r<i>`` (pass through each other, 1 m/s) starting on the points of
    ``starts`` (location ids) serve ``routes`` on ``_dead_end`` (service 30 s), with the
    watchdog (seeing the room queues only with ``sees_waits``): the robots' visits
    (location ids each), the orders given, and the queues at the end."""
    roadways = _dead_end()
    names = [f"r{i}" for i in range(len(starts))]
    lanes = SingleFileParams()
    builder = DiagramBuilder()
    allocator = builder.AddSystem(FixedSequenceAllocator(names, routes))
    queues = builder.AddSystem(RoomQueues(names, roadways.location_ids, rate_hz=10.0,
                                          segments=roadways.segment_count,
                                          exclusive=stop_segments(roadways, lanes)))
    robots = builder.AddSystem(FakeRobots([roadways.place(s).point for s in starts]))
    obeying = builder.AddSystem(_Obeying(names))
    watchdog = builder.AddSystem(DeadlockWatchdog(
        names, [0.22] * len(names), Costmap.from_obstacles(Obstacles(), BOUNDS),
        rate_hz=2.0, roadways=roadways))
    state = robots.GetOutputPort("state")
    builder.Connect(state, watchdog.GetInputPort("robot_state"))
    builder.Connect(watchdog.GetOutputPort("back_offs"), obeying.GetInputPort("back_offs"))
    if sees_waits:
        builder.Connect(queues.GetOutputPort("queue_state"),
                        watchdog.GetInputPort("queue_state"))
    generators = []
    for i, (robot, start) in enumerate(zip(names, starts, strict=True)):
        generator = builder.AddSystem(WaypointGenerator(
            names, i, roadways, start, WaypointParams(service_time=30.0, parking=False),
            rate_hz=10.0))
        builder.Connect(allocator.GetOutputPort("plan"), generator.GetInputPort("plan"))
        builder.Connect(state, generator.GetInputPort("robot_state"))
        builder.Connect(queues.GetOutputPort("queue_state"),
                        generator.GetInputPort("queue_state"))
        builder.Connect(watchdog.GetOutputPort("back_offs"), generator.GetInputPort("back_offs"))
        builder.Connect(generator.GetOutputPort("queue_request"),
                        queues.get_request_input_port(robot))
        builder.Connect(generator.GetOutputPort("queue_request"),
                        watchdog.GetInputPort(f"queue_request_{robot}"))
        builder.Connect(generator.GetOutputPort("progress"),
                        allocator.GetInputPort(f"progress_{robot}"))
        builder.Connect(generator.GetOutputPort("target"), obeying.GetInputPort(f"target_{i}"))
        builder.Connect(generator.GetOutputPort("target"),
                        watchdog.GetInputPort(f"target_{robot}"))
        builder.Connect(obeying.GetOutputPort(f"target_{i}"), robots.GetInputPort(f"target_{i}"))
        generators.append(generator)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(until)
    context = simulator.get_context()

    def value(system, port):
        return system.GetOutputPort(port).Eval(system.GetMyContextFromRoot(context))

    visits = [[v.location for v in value(g, "progress").visits] for g in generators]
    return visits, value(watchdog, "back_offs").history, value(queues, "queue_state")


def test_a_holder_leaving_through_the_segment_where_its_next_robot_queues_is_freed():
    # r1 serves R past the dead end; r0 comes to queue for R at the slot in the single-file
    # segment, which it holds, standing in it. r1, done, must leave through that segment:
    # each waits for the other (r1 keeps R, within release_distance of its point).
    stuck, orders, queues = _gridlock_run([H, R], [[R], [R, H]], until=150.0, sees_waits=False)
    assert stuck == [[], [R]] and orders == ()
    assert queues.room(R).holder == "r1" and queues.room(R).waiting == ("r0",)
    assert queues.segment_waiting == ("r1",)
    # The watchdog sends r0 (no holder) off the segment; r1 leaves, r0 serves R after it.
    visits, orders, _ = _gridlock_run([H, R], [[R], [R, H]], until=150.0)
    assert visits == [[R], [R, H]]
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    params = WatchdogParams()
    assert 30.0 + params.gridlock_time <= orders[0].issued <= 30.0 + params.gridlock_time + 25


def test_the_robot_in_the_segment_and_the_one_before_the_holder_in_line_give_way_at_once():
    # As above with r2 coming from G behind r0: it waits for the segment r0 holds, and it
    # asked before r1 (three robots in the gridlock). Freeing r1, the holder: r0, which
    # holds the segment r1 asks for, goes off the lane, and r2, before r1 in the segments'
    # line, stands where it is asking for nothing (else it would take the segment first
    # and gridlock with r1 in turn); all three get through.
    stuck, _, queues = _gridlock_run([H, R, G], [[R], [R, H], [R]], until=200.0,
                                     sees_waits=False)
    assert stuck == [[], [R], []]
    assert queues.segment_waiting == ("r2", "r1")
    visits, orders, _ = _gridlock_run([H, R, G], [[R], [R, H], [R]], until=300.0)
    assert visits == [[R], [R, H], [R]]
    assert [(o.robot, o.issued, o.releases) for o in orders] == [
        ("r0", orders[0].issued, True), ("r2", orders[0].issued, True)]
    assert orders[1].point == pytest.approx(tuple(_dead_end().node_position("J")), abs=1.6)
    assert orders[1].blockers == ("r1",)


@pytest.mark.parametrize("field", ["gridlock_time", "gridlock_cooldown"])
def test_gridlock_params_must_be_positive(field):
    with pytest.raises(InputError, match=field):
        WatchdogParams(**{field: 0.0})


def test_a_robot_giving_way_asks_only_for_the_segments_it_stands_in_and_no_room():
    # Driving home through the run W-J-S it needs segments 0 and 2; giving way (a
    # releases order in force) only the spur it stands in, and it stands.
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams(), home=(10.0, 5.0))
    route = ((0.0, 0.0), (10.0, 0.0), (10.0, 5.0))
    held = QueueState(segments=(SegmentHold(("r0",), True),) * 3)
    s = _Drive(phase=RobotMode.HOME, route=route, index=2)
    here = [[10.0, 3.0, 0.0, 0.5]]
    assert [k for k, _ in policy.update(s, _Inputs(10.0, held, here)).lanes.segments] == [0, 2]
    order = BackOff("r0", (12.0, 3.0), 9.0, 24.0, ("r1",), 0.0, releases=True)
    giving = policy.update(s, _Inputs(10.0, held, here, BackOffOrders((order,), (order,))))
    assert giving.lanes == Need(((2, True),), True, (2,), (2,)) and giving.giving_way
    assert not policy.outputs(giving).target.active
    # An order of the standstill rule (no releases) leaves its claims alone.
    plain = replace(order, releases=False)
    kept = policy.update(s, _Inputs(10.0, held, here, BackOffOrders((plain,), (plain,))))
    assert [k for k, _ in kept.lanes.segments] == [0, 2] and not kept.giving_way


def test_a_robot_giving_way_leaves_its_rooms_queue():
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r1", waiting=("r0",)),
                                              slot=0)
    step = stepper(generator, context, place.queue[0])
    step((30.0, 10.0), 0.0)
    assert generator.GetOutputPort("queue_request").Eval(context).room == B
    order = BackOff("r0", (0.0, 0.0), 0.0, 15.0, ("r1",), 0.0, releases=True)
    generator.GetInputPort("back_offs").FixValue(context, BackOffOrders((order,), (order,)))
    step((30.0, 10.0), 0.0)
    assert generator.GetOutputPort("queue_request").Eval(context).room is None
