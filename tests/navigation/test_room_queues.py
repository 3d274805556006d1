"""RoomQueues in a Simulator, its requests fixed by hand between steps."""

import random

import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake.navigation.room_queues import RoomQueues
from mrta_drake.payloads import QueueRequest, QueueState, RoomQueue, SegmentHold

ROOM, OTHER = 7, 8


class Bench:
    """A RoomQueues under a Simulator: ``ask`` sets a robot's request, ``step`` runs one
    queue update (10 Hz), ``queue`` reads a room's queue."""

    def __init__(self, robots, holders=None):
        self.queues = RoomQueues(robots, rooms=[ROOM, OTHER], rate_hz=10.0, holders=holders)
        self.simulator = Simulator(self.queues)
        self.context = self.simulator.get_mutable_context()
        for robot in robots:
            self.ask(robot)
        self.simulator.AdvanceTo(0.05)  # the update at t = 0

    def ask(self, robot, room=None, release=None):
        port = self.queues.get_request_input_port(robot)
        port.FixValue(self.context, Value[object](QueueRequest(robot, room, release)))

    def step(self, count=1):
        self.simulator.AdvanceTo(self.context.get_time() + 0.1 * count)

    def queue(self, room=ROOM) -> RoomQueue:
        state = self.queues.GetOutputPort("queue_state").Eval(self.context)
        return state.room(room)


def test_four_robots_get_the_room_one_at_a_time_in_request_order():
    bench = Bench(["r0", "r1", "r2", "r3"])
    for robot in ("r2", "r0", "r3", "r1"):
        bench.ask(robot, ROOM)
        bench.step()
    assert bench.queue() == RoomQueue(ROOM, "r2", ("r0", "r3", "r1"))
    holders = []
    for _ in range(4):
        holder = bench.queue().holder
        holders.append(holder)
        bench.ask(holder, None, release=ROOM)
        bench.step()
        assert bench.queue().holder != holder
        bench.ask(holder)  # done: no request at all
    assert holders == ["r2", "r0", "r3", "r1"]
    assert bench.queue() == RoomQueue(ROOM)


def test_same_tick_requests_queue_in_robot_order():
    bench = Bench(["a", "b", "c"])
    for robot in ("c", "b", "a"):
        bench.ask(robot, ROOM)
    bench.step()
    assert bench.queue() == RoomQueue(ROOM, "a", ("b", "c"))


def test_a_non_holder_release_changes_nothing():
    bench = Bench(["r0", "r1", "r2"])
    for robot in ("r0", "r1", "r2"):
        bench.ask(robot, ROOM)
        bench.step()
    before = bench.queue()
    assert before == RoomQueue(ROOM, "r0", ("r1", "r2"))
    bench.ask("r1", ROOM, release=ROOM)  # waiting, not holding
    bench.ask("r2", ROOM, release=OTHER)  # a room nobody holds
    bench.step(3)
    assert bench.queue() == before
    assert bench.queue(OTHER) == RoomQueue(OTHER)


def test_a_robot_that_stops_needing_the_room_leaves_the_queue():
    bench = Bench(["r0", "r1", "r2", "r3"])
    for robot in ("r0", "r1", "r2", "r3"):
        bench.ask(robot, ROOM)
        bench.step()
    bench.ask("r1")  # no longer wants anything
    bench.ask("r2", OTHER)  # wants another room instead
    bench.ask("r0", OTHER)  # the holder asks elsewhere but keeps ROOM until it releases it
    bench.step()
    assert bench.queue() == RoomQueue(ROOM, "r0", ("r3",))
    assert bench.queue(OTHER) == RoomQueue(OTHER, "r0", ("r2",))  # same tick: robot order
    bench.ask("r0", OTHER, release=ROOM)
    bench.step()
    assert bench.queue() == RoomQueue(ROOM, "r3")


def test_more_robots_than_slots_all_get_the_room_in_order():
    robots = [f"r{i}" for i in range(6)]  # rooms have 3 slots; the queue is not bounded
    bench = Bench(robots)
    for robot in robots:
        bench.ask(robot, ROOM)
    bench.step()
    assert bench.queue() == RoomQueue(ROOM, "r0", tuple(robots[1:]))
    served = []
    while bench.queue().holder is not None:
        holder = bench.queue().holder
        served.append(holder)
        bench.ask(holder, release=ROOM)
        bench.step()
    assert served == robots


def test_initial_holders():
    bench = Bench(["r0", "r1"], holders={ROOM: "r1"})
    bench.ask("r0", ROOM)
    bench.step()
    assert bench.queue() == RoomQueue(ROOM, "r1", ("r0",))
    with pytest.raises(ValueError):
        RoomQueues(["r0"], rooms=[ROOM], rate_hz=10.0, holders={ROOM: "nobody"})


def test_an_update_keeps_the_state_when_no_rule_applies():
    # The update keeps the old state object when it finds no rule to apply (most updates):
    # random requests from reachable states, the shortcut against the rules applied.
    robots = ["r0", "r1", "r2", "r3"]
    bench = Bench(robots, holders={OTHER: "r3"})
    queues, rng = bench.queues, random.Random(0)
    kept = 0
    for _ in range(300):
        for robot in rng.sample(robots, 2):
            bench.ask(robot, rng.choice([None, ROOM, OTHER, 99]),
                      rng.choice([None, None, ROOM, OTHER]))
        old = queues.GetOutputPort("queue_state").Eval(bench.context)
        requests = [queues.get_request_input_port(r).Eval(bench.context) for r in robots]
        bench.step()
        if not queues._changes_anything(old, requests):
            assert queues._applied(old, requests) == old
            assert queues.GetOutputPort("queue_state").Eval(bench.context) is old
            kept += 1
    assert 30 < kept < 270


class SegmentBench(Bench):
    """A RoomQueues with three single-file segments; ``want`` sets a robot's segments as
    (index, forward) pairs."""

    def __init__(self, robots, exclusive=frozenset()):
        self.queues = RoomQueues(robots, rooms=[ROOM], rate_hz=10.0, segments=3,
                                 exclusive=exclusive)
        self.simulator = Simulator(self.queues)
        self.context = self.simulator.get_mutable_context()
        for robot in robots:
            self.want(robot)
        self.simulator.AdvanceTo(0.05)

    def want(self, robot, *segments, room=None, stops=(), standing=()):
        port = self.queues.get_request_input_port(robot)
        port.FixValue(self.context, Value[object](QueueRequest(
            robot, room, segments=segments, stops=stops, standing=standing)))

    def state(self):
        return self.queues.GetOutputPort("queue_state").Eval(self.context)


def test_segments_are_granted_all_or_nothing_one_way_at_a_time():
    bench = SegmentBench(["a", "b", "c"])
    bench.want("a", (0, True), (1, True))
    bench.step()
    assert bench.state().holds_segments("a", ((0, True), (1, True)))
    bench.want("b", (1, False), (2, True))  # 1 the other way: waits, and gets not even 2
    bench.want("c", (0, True))  # same way as a: follows it in
    bench.step()
    state = bench.state()
    assert state.segment_waiting == ("b",)
    assert state.segments[2].holders == () and state.segments[0].holders == ("a", "c")
    bench.want("a", (1, True))  # a is out of segment 0
    bench.want("c")  # c is through
    bench.step()
    assert bench.state().segment_waiting == ("b",)
    bench.want("a")  # a is out: b gets both
    bench.step()
    state = bench.state()
    assert state.segment_waiting == ()
    assert state.holds_segments("b", ((1, False), (2, True))) and not state.segments[1].forward


def test_robots_standing_together_in_a_segment_turn_when_they_all_want_out():
    # a and b drove into a dead-end segment one after the other and stand there; both now
    # want out, the other way: they turn together (each waited for the other before,
    # their hold keeping the way in: office seeds 1, 3, 5 at a charger). With one of them
    # still naming the way in, the hold keeps it and the other waits.
    bench = SegmentBench(["a", "b", "c"])
    bench.want("a", (0, True), stops=(0,))
    bench.want("b", (0, True), stops=(0,))
    bench.step()
    bench.want("a", (0, False), (1, True))
    bench.step()
    state = bench.state()
    assert state.segments[0] == SegmentHold(("a", "b"), True, ("a",))
    assert state.segment_waiting == ("a",)
    bench.want("b", (0, False), (1, True))
    bench.want("c", (0, True))  # outside, the way in: waits for them to leave
    bench.step()
    state = bench.state()
    assert state.segments[0] == SegmentHold(("a", "b"), False, ("c",))
    assert state.holds_segments("a", ((0, False), (1, True)))
    assert state.holds_segments("b", ((0, False), (1, True)))
    assert state.segment_waiting == ("c",)


def test_a_robot_waiting_first_keeps_its_turn():
    bench = SegmentBench(["a", "b", "c"])
    bench.want("a", (0, True))
    bench.step()
    bench.want("b", (0, False))
    bench.step()
    bench.want("c", (0, True))  # could follow a in, but b waits for 0 first
    bench.step()
    assert bench.state().segment_waiting == ("b", "c")
    assert bench.state().segments[0].waiting == ("b", "c")  # both name it
    bench.want("a")
    bench.step()
    state = bench.state()
    assert state.segments[0].holders == ("b",) and state.segment_waiting == ("c",)


def test_a_segment_where_robots_stop_is_held_by_one_robot_at_a_time():
    bench = SegmentBench(["a", "b"], exclusive=frozenset({0}))
    bench.want("a", (0, True), stops=(0,))
    bench.step()
    bench.want("b", (0, True))  # the same way, but a stops in 0 and may turn: b waits
    bench.step()
    state = bench.state()
    assert state.segments[0].holders == ("a",) and state.segment_waiting == ("b",)
    bench.want("a", (0, False), stops=(0,))  # a, alone in it, turns
    bench.step()
    state = bench.state()
    assert state.segments[0] == SegmentHold(("a",), False, ("b",))
    assert state.segment_waiting == ("b",)
    bench.want("a")
    bench.step()
    assert bench.state().segments[0].holders == ("b",)


def test_robots_driving_through_a_segment_where_robots_stop_follow_each_other_in():
    bench = SegmentBench(["a", "b", "c"], exclusive=frozenset({0}))
    bench.want("a", (0, True))  # a and b only drive through 0, the same way
    bench.step()
    bench.want("b", (0, True))
    bench.want("c", (0, True), stops=(0,))  # c will stop in it: it waits for them both
    bench.step()
    state = bench.state()
    assert state.segments[0].holders == ("a", "b") and state.segment_waiting == ("c",)
    bench.want("a")
    bench.want("b")
    bench.step()
    assert bench.state().segments[0].holders == ("c",)
    bench.want("a", (0, True))  # c stops in it: a, driving through, waits
    bench.step()
    assert bench.state().segment_waiting == ("a",)


def test_of_robots_asking_at_once_the_one_standing_in_the_segment_goes_first():
    # At the start, a (driving in from outside) and b (standing in 0, nothing to do) ask
    # for 0 at the same instant: b, already in it, gets it; a waits (and b, told so by
    # the segment's waiting robots, drives out of its way).
    bench = SegmentBench(["a", "b"], exclusive=frozenset({0}))
    bench.want("a", (0, True), (1, True))
    bench.want("b", (0, True), stops=(0,), standing=(0,))
    bench.step()
    state = bench.state()
    assert state.segments[0].holders == ("b",) and state.segment_waiting == ("a",)
    assert state.segments[0].waiting == ("a",)


def test_a_robot_standing_in_a_segment_gets_the_next_before_robots_outside():
    # a stands in 0 and needs 1 (a segment where robots stop) to drive on; b, outside,
    # asked for 1 first. Granting b first would leave a holding 0 while waiting for 1.
    bench = SegmentBench(["a", "b", "c"], exclusive=frozenset({1}))
    bench.want("c", (1, True), stops=(1,))  # c stands in 1
    bench.want("a", (0, True))
    bench.step()
    bench.want("b", (1, False))
    bench.step()
    bench.want("a", (0, True), (1, True))
    bench.step()
    assert bench.state().segment_waiting == ("a", "b")  # a, standing in 0, first
    bench.want("c")
    bench.step()
    state = bench.state()
    assert state.holds_segments("a", ((0, True), (1, True)))
    assert state.segment_waiting == ("b",)


def test_a_robot_standing_in_a_segment_passes_one_waiting_for_that_segment():
    # a stands in 2, b in 1; a, waiting first, wants 0 and 1, b wants 0: b goes first
    # (letting a's turn hold b back would wait for ever).
    bench = SegmentBench(["a", "b", "c"], exclusive=frozenset({1, 2}))
    bench.want("c", (0, True))
    bench.want("b", (1, True), stops=(1,))
    bench.want("a", (2, True), stops=(2,))
    bench.step()
    bench.want("a", (2, True), (0, True), (1, True), stops=(2,))
    bench.step()
    bench.want("b", (0, True), (1, True), stops=(1,))
    bench.want("c")
    bench.step()
    state = bench.state()
    assert state.holds_segments("b", ((0, True), (1, True)))
    assert state.segment_waiting == ("a",)


def test_a_robot_keeps_no_turn_that_waits_for_the_robot_behind_it():
    # h holds the room and, to leave, wants 1; q waits for the room standing in 0 (where
    # robots stop); w, waiting first, wants 0 and 1. w waits for q, q for h: w keeping its
    # turn on 1 before h would wait for ever (office seed 3), so h goes. x, for whom w
    # does not wait, still waits its turn behind w.
    bench = SegmentBench(["h", "q", "w", "x"], exclusive=frozenset({0}))
    bench.want("h", room=ROOM)
    bench.want("q", (0, True), stops=(0,))
    bench.step()
    bench.want("q", (0, True), room=ROOM, stops=(0,))
    bench.want("w", (0, True), (1, True))
    bench.step()
    assert bench.state().segment_waiting == ("w",)
    bench.want("h", (1, False), room=ROOM)
    bench.want("x", (1, False))
    bench.step()
    state = bench.state()
    assert state.holds_segments("h", ((1, False),))
    assert state.segment_waiting == ("w", "x")
    bench.want("h")
    bench.want("q")
    bench.step()
    state = bench.state()
    assert state.holds_segments("w", ((0, True), (1, True)))
    assert state.segment_waiting == ("x",)


def test_the_room_holder_on_its_way_in_gets_a_segment_before_robots_that_would_stop_there():
    # h holds the room and, to drive in, wants 0 (where robots stop: the room's queue
    # slot is in it); q, waiting for 0 first, drives to that queue slot and would wait
    # there for h, h for q's segment (the fork's older office, seed 0): h goes first.
    bench = SegmentBench(["h", "q", "c"], exclusive=frozenset({0}))
    bench.want("h", room=ROOM)
    bench.want("c", (0, True), stops=(0,))  # c stands in 0
    bench.step()
    bench.want("q", (1, True), (0, True), stops=(0,))
    bench.step()
    bench.want("h", (0, True), room=ROOM, stops=(0,))
    bench.step()
    assert bench.state().segments[0].waiting == ("q", "h")
    bench.want("c")
    bench.step()
    state = bench.state()
    assert state.holds_segments("h", ((0, True),))
    assert state.segment_waiting == ("q",)
    bench.want("h", room=ROOM)  # h is in the room
    bench.step()
    assert bench.state().holds_segments("q", ((0, True), (1, True)))


class _QueueReader(LeafSystem):
    """Reads ``queue_state`` into an output and counts how often that output is computed."""

    def __init__(self):
        super().__init__()
        self.computed = 0
        port = self.DeclareAbstractInputPort("queue_state", Value[object](QueueState()))

        def calc(context, output):
            self.computed += 1
            output.set_value(port.Eval(context))

        self.output = self.DeclareAbstractOutputPort(
            "copy", lambda: Value[object](QueueState()), calc,
            prerequisites_of_calc={port.ticket()})


def test_an_update_that_changes_nothing_leaves_what_reads_the_queues_cached():
    # The queues report DidNothing, so Drake applies no update and what is computed from
    # their state stays cached; a granted request changes the state and is computed again.
    builder = DiagramBuilder()
    queues = builder.AddSystem(RoomQueues(["r0"], rooms=[ROOM], rate_hz=10.0))
    reader = builder.AddSystem(_QueueReader())
    builder.Connect(queues.GetOutputPort("queue_state"), reader.get_input_port())
    builder.ExportInput(queues.get_request_input_port("r0"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    reader_context = reader.GetMyContextFromRoot(context)
    diagram.get_input_port().FixValue(context, Value[object](QueueRequest("r0")))
    for k in range(6):
        simulator.AdvanceTo(0.05 + 0.1 * k)
        reader.output.Eval(reader_context)
    assert reader.computed == 1
    diagram.get_input_port().FixValue(context, Value[object](QueueRequest("r0", ROOM)))
    simulator.AdvanceTo(0.65)
    assert reader.output.Eval(reader_context).room(ROOM).holder == "r0"
    assert reader.computed == 2
