"""Gridlocks of waits: robots waiting for rooms and single-file segments held by each other,
found from the room queues' facts (``standstills.waits_for``, ``standstills.gridlocks``) and
broken by the deadlock watchdog (``releases`` orders, step 5 of ``DeadlockWatchdog``)."""

from dataclasses import replace

import numpy as np
import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake.allocation.fixed_sequence_allocator import FixedSequenceAllocator
from mrta_drake.errors import InputError
from mrta_drake.navigation.costmap import Costmap
from mrta_drake.navigation.deadlock_watchdog import (
    DeadlockWatchdog,
    WatchdogParams,
    _WatchdogState,
)
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.room_queues import RoomQueues
from mrta_drake.navigation.single_file import Need, SingleFileParams, stop_segments
from mrta_drake.navigation.standstills import (
    gridlocks,
    wait_cycles,
    waits_for,
)
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
from mrta_drake.world.obstacles import Box, Obstacles
from mrta_drake.world.segment_distances import distance_to_polyline
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


def test_wait_cycles_count_a_robot_standing_in_a_segment_another_asks_for():
    # a holds a room and its segments 0 and 1 (granted: it waits for nobody) but b, which
    # waits for a's room, stands in segment 1: a waits for b as surely as b for a.
    waits = {"b": {"a"}, "c": {"b"}, "d": {"e"}}
    asks = {"a": {0, 1}, "b": {1}, "c": {1}, "e": {2}}
    stands = {"b": {1}, "d": {2}}
    assert wait_cycles(waits, asks, stands, ["a", "b", "c", "d", "e"]) == [
        ("a", "b"), ("d", "e")]  # c only waits behind the cycle
    assert wait_cycles(waits, asks, stands, ["b", "c", "d", "e"]) == [("d", "e")]  # a moves
    assert wait_cycles(waits, asks, {}, ["a", "b", "c", "d", "e"]) == []  # a chain


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
    # A cycle of waits: the watchdog sends r0 (no holder, standing in the segment r1 asks
    # for) off the segment once the cycle has lasted cycle_time, long before a gridlock's
    # gridlock_time; r1 leaves, r0 serves R after it.
    visits, orders, _ = _gridlock_run([H, R], [[R], [R, H]], until=150.0)
    assert visits == [[R], [R, H]]
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    params = WatchdogParams()
    assert orders[0].issued - orders[0].stalled_since == pytest.approx(params.cycle_time)
    assert 30.0 + params.cycle_time <= orders[0].issued < 30.0 + params.gridlock_time


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


@pytest.mark.parametrize("field", ["gridlock_time", "gridlock_cooldown", "cycle_time"])
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


def _watchdog_of(state, targets, requests, queues, roadways=None, obstacles=None):
    """The watchdog alone with robots r0, r1, ... (0.22 m), one per request, on the costmap
    of ``obstacles`` (None: empty), its inputs fixed: ``state`` the robots' (x, y, theta,
    v), ``targets`` and ``requests`` one each (r0's first), ``queues`` the queue state.
    Returns the watchdog and its context."""
    names = [f"r{i}" for i in range(len(requests))]
    watchdog = DeadlockWatchdog(names, [0.22] * len(names),
                                Costmap.from_obstacles(obstacles or Obstacles(), BOUNDS),
                                rate_hz=2.0, roadways=roadways)
    context = watchdog.CreateDefaultContext()
    watchdog.GetInputPort("robot_state").FixValue(context, list(state))
    for target, request in zip(targets, requests, strict=True):
        watchdog.GetInputPort(f"target_{target.robot}").FixValue(context, target)
        watchdog.GetInputPort(f"queue_request_{request.robot}").FixValue(context, request)
    watchdog.GetInputPort("queue_state").FixValue(context, queues)
    return watchdog, context


def test_robots_rocking_on_the_spot_in_a_cycle_of_waits_are_freed_within_seconds():
    # r1 holds room 0 and waits for segment 0, where r0 stands waiting for the room: a
    # cycle of waits. Both rock on the spot (0.1 m/s, never getting anywhere): moving, so
    # no gridlock of waits, yet standing still; r0 gives way once r1 has made no progress
    # for cycle_time and the cycle has lasted cycle_time.
    watchdog, context = _watchdog_of(
        [0.0, 0.0, 0.0, 0.1, 3.0, 0.0, 0.0, -0.1],
        (WaypointTarget("r0"), WaypointTarget("r1", True, (-8.0, 0.0), None, True)),
        (QueueRequest("r0", 0, segments=((0, True),), standing=(0,)),
         QueueRequest("r1", segments=((0, True),))),
        QueueState((RoomQueue(0, "r1", ("r0",)),), segments=(SegmentHold(("r0",)),),
                   segment_waiting=("r1",)))
    simulator = Simulator(watchdog, context)
    simulator.AdvanceTo(15.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history
    params = WatchdogParams()
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    assert orders[0].issued == pytest.approx(2 * params.cycle_time)


def _holder_standing_idle(r1_states):
    """The watchdog alone: r1 holds room 0 standing at (3, 0) with its target inactive, r0
    waits for the room at (0, 0) (at its slot, no goal); r1's state (x, y, theta, v) is
    ``r1_states[k]`` from ``k`` seconds on. The orders given by 45 s."""
    watchdog = DeadlockWatchdog(["r0", "r1"], [0.22, 0.22],
                                Costmap.from_obstacles(Obstacles(), BOUNDS), rate_hz=2.0)
    context = watchdog.CreateDefaultContext()
    watchdog.GetInputPort("target_r0").FixValue(
        context, WaypointTarget("r0", True, (0.0, 0.0), None, True))
    watchdog.GetInputPort("target_r1").FixValue(context, WaypointTarget("r1"))
    watchdog.GetInputPort("queue_state").FixValue(
        context, QueueState((RoomQueue(0, "r1", ("r0",)),)))
    watchdog.GetInputPort("queue_request_r0").FixValue(context, QueueRequest("r0", 0))
    watchdog.GetInputPort("queue_request_r1").FixValue(context, QueueRequest("r1", 0))
    simulator = Simulator(watchdog, context)
    for k, r1 in enumerate((*r1_states, r1_states[-1])):
        watchdog.GetInputPort("robot_state").FixValue(
            simulator.get_mutable_context(), [0.0, 0.0, 0.0, 0.0, *r1])
        simulator.AdvanceTo(45.0 if k == len(r1_states) else k + 1.0)
    return watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history


def test_a_robot_waiting_for_a_holder_standing_with_nothing_to_do_gives_way():
    # A room's holder with its target inactive serves nothing (the run recorder counts the
    # robot waiting for it as stuck): a gridlock of waits, broken after gridlock_time.
    orders = _holder_standing_idle([(3.0, 0.0, 0.0, 0.0)])
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    assert orders[0].issued == pytest.approx(WatchdogParams().gridlock_time)


def test_a_gridlocks_time_goes_on_through_a_break_in_which_its_robot_still_waits():
    # The holder stirs for 2 s (moving: live, so r0's wait leads somewhere) and stands
    # again where it stood: r0, waiting where it stood all along, is in the gridlock since
    # 0 s, the 2 s not counted.
    still, stirring = (3.0, 0.0, 0.0, 0.0), (3.1, 0.0, 0.0, 0.2)
    orders = _holder_standing_idle([still] * 8 + [stirring] * 2 + [still])
    assert [(o.robot, o.releases) for o in orders] == [("r0", True)]
    assert orders[0].issued == pytest.approx(WatchdogParams().gridlock_time + 2.0)


def test_a_robot_standing_aside_holding_segments_others_wait_for_lets_them_go():
    # r1 was sent aside by the standstill rule (an order without releases: it keeps its
    # claims) and stands at its spot holding segment 0, which r0 waits for: once the
    # gridlock has lasted gridlock_time, r1's order goes on as a releases order (same spot,
    # same end), so r0 gets the segment.
    watchdog = DeadlockWatchdog(["r0", "r1"], [0.22, 0.22],
                                Costmap.from_obstacles(Obstacles(), BOUNDS), rate_hz=2.0)
    context = watchdog.CreateDefaultContext()
    aside = BackOff("r1", (3.0, 0.0), 0.0, 100.0, ("r2",), 0.0, arrived=0.0)
    context.get_mutable_abstract_state(0).set_value(_WatchdogState(
        (None, None), BackOffOrders((aside,), (aside,)), gridlocked=(None, None),
        cycled=(None, None)))
    watchdog.GetInputPort("robot_state").FixValue(
        context, [0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    watchdog.GetInputPort("target_r0").FixValue(
        context, WaypointTarget("r0", True, (0.0, 0.0), None, True))
    watchdog.GetInputPort("target_r1").FixValue(context, WaypointTarget("r1"))
    watchdog.GetInputPort("queue_state").FixValue(context, QueueState(
        segments=(SegmentHold(("r1",)),), segment_waiting=("r0",)))
    watchdog.GetInputPort("queue_request_r0").FixValue(
        context, QueueRequest("r0", segments=((0, True),)))
    watchdog.GetInputPort("queue_request_r1").FixValue(
        context, QueueRequest("r1", segments=((0, True),)))
    simulator = Simulator(watchdog, context)
    simulator.AdvanceTo(30.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context())
    assert orders.active == (replace(aside, issued=WatchdogParams().gridlock_time,
                                     blockers=("r0",), releases=True),)
    assert orders.history == (aside, orders.active[0])


def test_a_rooms_holder_standing_in_the_segment_a_cycle_waits_for_gives_way_last():
    # r1 holds room 0 and, leaving, stands in segment 0 (off its room's point, so serving
    # nothing) waiting for the segment, which r0 holds and asks for, kept out by r1: a
    # cycle of waits whose only robot in another's way is the holder. No other robot of
    # the cycle can be moved, so the holder gives way once the cycle has lasted cycle_time.
    watchdog, context = _watchdog_of(
        [0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0],
        (WaypointTarget("r0", True, (8.0, 0.0), None, True),
         WaypointTarget("r1", True, (-8.0, 0.0), None, True)),
        (QueueRequest("r0", segments=((0, True),)),
         QueueRequest("r1", segments=((0, True),), standing=(0,))),
        QueueState((RoomQueue(0, "r1"),), segments=(SegmentHold(("r0",)),),
                   segment_waiting=("r1",)))
    simulator = Simulator(watchdog, context)
    simulator.AdvanceTo(WatchdogParams().gridlock_time + 5.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r1", True, ("r0",))]
    assert orders[0].issued == pytest.approx(WatchdogParams().gridlock_time)


def _door_waits(r0_request, r1_request, queues, until):
    """The watchdog alone on ``_dead_end``: r0 stands still in room H's doorway at
    (0.8, 0.9), r1 at (3, 0) at its target (holding a room, so serving as the recorder
    counts it); each asks as given. The orders given by ``until`` (s)."""
    watchdog, context = _watchdog_of(
        [0.8, 0.9, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0],
        (WaypointTarget("r0", True, (0.8, 0.9), None, True),
         WaypointTarget("r1", True, (3.0, 0.0), None, True)),
        (r0_request, r1_request), queues, roadways=_dead_end())
    simulator = Simulator(watchdog, context)
    simulator.AdvanceTo(until)
    return watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history


def test_a_robot_in_the_doorway_of_a_holder_it_waits_for_gives_way():
    # Office seed 11: r1 holds room G, which it left, and room H, and waits at H's door for
    # r0, which stands in H's doorway queueing for G: the two wait for each other, though
    # the recorder counts r1 (at its slot, holding a room) as serving. r0 gives way once
    # the cycle has lasted cycle_time, to a spot off H's doorway.
    orders = _door_waits(QueueRequest("r0", G), QueueRequest("r1", H, door=("r0",)),
                         QueueState((RoomQueue(G, "r1", ("r0",)), RoomQueue(H, "r1"))),
                         WatchdogParams().gridlock_time + 5.0)
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    assert orders[0].issued == pytest.approx(WatchdogParams().cycle_time)
    doorway = _dead_end().place(H).doorway
    assert distance_to_polyline(np.array([orders[0].point]), doorway)[0] > 0.22 + 0.22


def test_two_holders_each_in_the_others_doorway_one_gives_way_after_gridlock_time():
    # Office seed 11 (docs/worlds.md, "A robot holding the room it left"): robot5 waited at
    # patrol_A1's door for robot6, pantry's holder, standing in its doorway, and robot6 at
    # pantry's door for robot5 until door_patience (30 s) ran out. Both hold rooms: one
    # gives way once the cycle has lasted gridlock_time (rooms' holders last).
    orders = _door_waits(QueueRequest("r0", G, door=("r1",)),
                         QueueRequest("r1", H, door=("r0",)),
                         QueueState((RoomQueue(G, "r0"), RoomQueue(H, "r1"))),
                         WatchdogParams().gridlock_time + 5.0)
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r1", True, ("r0",))]
    assert orders[0].issued == pytest.approx(WatchdogParams().gridlock_time)


def test_a_holder_whose_way_a_boxed_in_robot_waiting_for_it_stands_in_gives_way():
    # Office seed 24: r0 holds room R and segment 0 and drives east to its point at a
    # corridor's dead end; r1, waiting for segment 0 with its target inactive, stands in
    # r0's way with no spot to go to (the corridor's end behind it, r0 before it): a
    # gridlock of waits (r0 stands, serving nothing) in which no robot may give way (r0
    # holds a room; r1 has no spot) and no cycle (r1 stands in no segment r0 asks for).
    # r1 is boxed in, so r0 gives way to it once the gridlock has lasted gridlock_time (a
    # releases order: it lets segment 0 go), to a spot off r1's way.
    watchdog, context = _watchdog_of(
        [15.6, 0.0, 0.0, 0.0, 16.5, 0.0, np.pi, 0.0],
        (WaypointTarget("r0", True, (17.0, 0.0), None, True), WaypointTarget("r1")),
        (QueueRequest("r0", R, segments=((0, True),)),
         QueueRequest("r1", segments=((0, False),))),
        QueueState((RoomQueue(R, "r0"),), segments=(SegmentHold(("r0",)),),
                   segment_waiting=("r1",)),
        obstacles=_corridor_to_dead_end(12.0, 17.6))
    simulator = Simulator(watchdog, context)
    params = WatchdogParams()
    simulator.AdvanceTo(params.gridlock_time + 5.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    assert orders[0].issued == pytest.approx(params.gridlock_time)
    assert orders[0].point[0] < 15.6 - params.back_off_distance + 1e-9  # back, off r1's way


def test_a_robot_queueing_in_its_rooms_holders_way_out_goes_on_ahead_at_once():
    # Office seed 26 (docs/worlds.md, "A robot queueing in its room's holder's way out"):
    # r1 holds room R and segment 0 and leaves the room west along the 2 m wide corridor
    # (its dead end behind r1); r0 queues for R at an overflow spot inside segment 0, face
    # to face with r1: a cycle of waits (r0 waits for the holder, r1 asks for the segment
    # r0 stands in). Every spot within search_reach lies on r1's way, so none is off it:
    # r0 is sent on ahead along that way once the cycle has lasted cycle_time (a releases
    # order: it leaves the queue while r1 passes), not after twice standstill_time.
    watchdog, context = _watchdog_of(
        [14.6, 0.0, 0.0, 0.0, 15.6, 0.0, np.pi, 0.0],
        (WaypointTarget("r0", True, (14.6, 0.0), None, True),
         WaypointTarget("r1", True, (-8.0, 0.0), None, True)),
        (QueueRequest("r0", R, standing=(0,)),
         QueueRequest("r1", segments=((0, False),), standing=(0,))),
        QueueState((RoomQueue(R, "r1", ("r0",)),), segments=(SegmentHold(("r1",), False),)),
        obstacles=_corridor_to_dead_end(4.0, 18.0))
    simulator = Simulator(watchdog, context)
    params = WatchdogParams()
    simulator.AdvanceTo(params.standstill_time)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history
    assert [(o.robot, o.releases, o.blockers) for o in orders] == [("r0", True, ("r1",))]
    assert orders[0].issued == pytest.approx(params.cycle_time)
    assert orders[0].point[0] < 14.6 - params.back_off_distance + 1e-9  # on ahead, west


def test_robots_beside_a_boxed_in_robot_others_wait_for_step_aside():
    # Office seed 64: r0 queues for room R at an overflow spot inside segment 0, which it
    # holds, boxed in by the corridor's dead end and by r2, standing beside it; R's holder
    # r1 waits for segment 0 to leave, and r2 (holding room H) waits for it too. No robot
    # may give way (r0 has no spot, r1 and r2 hold rooms) and none stands in the way of a
    # robot it waits for, so once the gridlock has lasted gridlock_time r2, within
    # back_off_distance of r0, is sent aside (west, keeping room H), and r0 has room.
    watchdog, context = _watchdog_of(
        [16.5, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 15.6, 0.0, 0.0, 0.0],
        (WaypointTarget("r0", True, (16.5, 0.0), None, True), WaypointTarget("r1"),
         WaypointTarget("r2")),
        (QueueRequest("r0", R, standing=(0,)), QueueRequest("r1", segments=((0, True),)),
         QueueRequest("r2", segments=((0, True),))),
        QueueState((RoomQueue(R, "r1", ("r0",)), RoomQueue(H, "r2")),
                   segments=(SegmentHold(("r0",), False),), segment_waiting=("r1", "r2")),
        obstacles=_corridor_to_dead_end(4.0, 17.6))
    simulator = Simulator(watchdog, context)
    params = WatchdogParams()
    simulator.AdvanceTo(params.gridlock_time + 5.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history
    assert [(o.robot, o.releases) for o in orders] == [("r2", True)]
    assert orders[0].issued == pytest.approx(params.gridlock_time)
    assert orders[0].point[0] < 15.6 - params.back_off_distance + 1e-9  # west, away


def _corridor_to_dead_end(west: float, east: float) -> Obstacles:
    """A 2 m wide corridor along y = 0 (walls 0.1 m thick) from x = ``west``, open, to its
    dead end at x = ``east`` (m)."""
    t, middle, length = 0.1, (west + east) / 2, east - west
    return Obstacles((
        Box("south", (middle, -1.0 - t / 2), (length, t)),
        Box("north", (middle, 1.0 + t / 2), (length, t)),
        Box("end", (east + t / 2, 0.0), (t, 2.0 + 2 * t)),
    ))
