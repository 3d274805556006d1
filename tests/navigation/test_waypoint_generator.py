"""WaypointGenerators, RoomQueues and fake robots in a small lane loop, in a Simulator."""

import math

import numpy as np
import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake.allocation.fixed_sequence_allocator import FixedSequenceAllocator
from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.room_queues import RoomQueues
from mrta_drake.navigation.single_file import NOTHING, Need
from mrta_drake.navigation.waypoint_generator import (
    WaypointGenerator,
    WaypointParams,
    WaypointPolicy,
    _Drive,
)
from mrta_drake.payloads import (
    NO_BACK_OFFS,
    NO_DISTURBANCES,
    Breakdown,
    Disturbances,
    FleetPlan,
    LiftState,
    QueueState,
    RobotMode,
    RobotPlan,
    RoomQueue,
    SegmentHold,
    Stop,
    WaypointTarget,
)
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig

A, B, C = 0, 1, 2


def loop_world(parking: bool = False, overflow=()) -> Roadways:
    """As in test_roadways: an eastbound lane at y = 0 and a westbound one at y = 1.5 joined
    at x = 0 and 30; rooms A, B, C at x = 5, 15, 25, point at y = 5, door at y = 2.5, three
    queue slots east of the door on the westbound lane; with ``parking``, a parking spot 2 m
    east of each point; ``overflow``: each location's overflow spots, (dx, y) m from its
    point's x."""
    xs = (0, 10, 20, 30)
    nodes = {f"S{x}": [x, 0.0] for x in xs} | {f"N{x}": [x, 1.5] for x in xs}
    edges = [["S0", "S10"], ["S10", "S20"], ["S20", "S30"], ["S30", "N30"],
             ["N30", "N20"], ["N20", "N10"], ["N10", "N0"], ["N0", "S0"]]
    locations = [
        LocationConfig(
            id=i, point=[x, 5.0], queue=[[x + 1.0, 1.5], [x + 2.0, 1.5], [x + 3.0, 1.5]],
            entry=[[x, 2.5]], exit_node=f"N{x - 5}", approach_node=f"N{x + 5}",
            parking=[[x + 2.0, 5.0], [x + 2.0, 6.5]] if parking else [],
            overflow=[[x + dx, y] for dx, y in overflow],
        )
        for i, x in enumerate((5, 15, 25))
    ]
    return Roadways(RoadwaysConfig(nodes=nodes, edges=edges), locations)


class FakeRobots(LeafSystem):
    """Robots that drive straight at their target's current waypoint at 1 m/s (20 Hz), and
    pass through each other. Inputs ``target_<i>``; output ``state`` (4N)."""

    def __init__(self, starts, speed=1.0, period=0.05):
        super().__init__()
        self._speed, self._period = speed, period
        initial = np.concatenate([[x, y, 0.0, 0.0] for x, y in starts])
        self._state = self.DeclareDiscreteState(initial)
        self._targets = [
            self.DeclareAbstractInputPort(f"target_{i}", Value[object](WaypointTarget(str(i))))
            for i in range(len(starts))
        ]
        self.DeclareStateOutputPort("state", self._state)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._move)

    def _move(self, context, discrete_state):
        x = context.get_discrete_state(self._state).get_value().copy()
        for i, port in enumerate(self._targets):
            target = port.Eval(context)
            if not target.active:
                x[4 * i + 3] = 0.0
                continue
            gap = np.asarray(target.current) - x[4 * i:4 * i + 2]
            distance = float(np.linalg.norm(gap))
            step = min(distance, self._speed * self._period)
            if distance > 0:
                x[4 * i:4 * i + 2] += gap / distance * step
                x[4 * i + 2] = math.atan2(gap[1], gap[0])
            x[4 * i + 3] = step / self._period
        discrete_state.get_mutable_vector(self._state).SetFromVector(x)


class ScriptedPlan(LeafSystem):
    """Output ``plan``: the last of ``plans`` (start time, FleetPlan) that has started."""

    def __init__(self, plans):
        super().__init__()
        self._plans = plans
        self.DeclareAbstractOutputPort(
            "plan", lambda: Value[object](plans[0][1]), self._calc,
            prerequisites_of_calc={self.time_ticket()},
        )

    def _calc(self, context, output):
        output.set_value([p for t, p in self._plans if t <= context.get_time()][-1])


class World:
    """Robots ``r0, r1, ...`` starting on the points of ``starts`` (location ids)."""

    def __init__(self, starts, plan_source, start_known=True, params=None, parking=False,
                 homes=None, at=None, overflow=()):
        """``homes``: start spots (x, y) off the locations instead, one per robot (each
        robot's home; all of them its spots); ``at``: where the robots stand at first (x, y)
        if not there; ``overflow``: as ``loop_world``'s."""
        self.roadways = roadways = loop_world(parking, overflow)
        self.robots = [f"r{i}" for i in range(len(starts))]
        builder = DiagramBuilder()
        plan = builder.AddSystem(plan_source)
        queues = builder.AddSystem(RoomQueues(self.robots, roadways.location_ids, rate_hz=10.0))
        fake = builder.AddSystem(FakeRobots(at or homes or [roadways.place(s).point
                                                             for s in starts]))
        self.generators = []
        for i, (robot, start) in enumerate(zip(self.robots, starts, strict=True)):
            generator = builder.AddSystem(WaypointGenerator(
                self.robots, i, roadways, start if start_known else None,
                params or WaypointParams(), None if homes is None else homes[i], homes or (),
                rate_hz=10.0,
            ))
            builder.Connect(plan.GetOutputPort("plan"), generator.GetInputPort("plan"))
            builder.Connect(fake.GetOutputPort("state"), generator.GetInputPort("robot_state"))
            builder.Connect(
                queues.GetOutputPort("queue_state"), generator.GetInputPort("queue_state")
            )
            builder.Connect(
                generator.GetOutputPort("queue_request"), queues.get_request_input_port(robot)
            )
            builder.Connect(generator.GetOutputPort("target"), fake.GetInputPort(f"target_{i}"))
            if isinstance(plan_source, FixedSequenceAllocator):
                builder.Connect(
                    generator.GetOutputPort("progress"), plan.GetInputPort(f"progress_{robot}")
                )
            self.generators.append(generator)
        self.queues, self.fake = queues, fake
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.log = []  # (t, queue state, positions (N, 2), targets) at every 0.1 s, mid-tick

    def _eval(self, system, port):
        return system.GetOutputPort(port).Eval(system.GetMyContextFromRoot(self.context))

    def run(self, until):
        while self.context.get_time() < until:
            self.simulator.AdvanceTo(round(self.context.get_time() * 10) / 10 + 0.15)
            positions = self._eval(self.fake, "state").reshape(-1, 4)[:, :2].copy()
            targets = [self._eval(g, "target") for g in self.generators]
            self.log.append((self.context.get_time(), self._eval(self.queues, "queue_state"),
                             positions, targets))

    def progress(self, i):
        return self._eval(self.generators[i], "progress")

    def distance(self, positions, i, location):
        return float(np.linalg.norm(positions[i] - self.roadways.place(location).point))


def fixed(*routes):
    return FixedSequenceAllocator([f"r{i}" for i in range(len(routes))], routes)


def test_robots_visit_in_order_queue_enter_and_release():
    world = World([C, C], fixed([B, A, C], [B]))
    world.run(until=100)
    r0, r1 = world.progress(0), world.progress(1)
    assert [(v.key, v.location) for v in r0.visits] == [
        ("r0/visit0", B), ("r0/visit1", A), ("r0/visit2", C)
    ]
    assert [(v.key, v.location) for v in r1.visits] == [("r1/visit0", B)]
    assert r0.last_location == C and r0.current_stop is None
    times = [v.time for v in r0.visits]
    assert times == sorted(times)
    for (a, b), time in zip(((C, B), (B, A), (A, C)), np.diff([0.0, *times]), strict=True):
        # Each leg at 1 m/s, cutting corners by at most the tolerances, plus 1 s of service.
        assert world.roadways.leg_length(a, b) - 6 < time < world.roadways.leg_length(a, b) + 8

    b_queue = [(t, state.room(B), positions, targets)
               for t, state, positions, targets in world.log]
    # Both arrive together; r0 (robot order) gets B while r1 waits at the head slot.
    waiting = [(t, targets[1]) for t, q, _, targets in b_queue
               if q.holder == "r0" and q.waiting == ("r1",)]
    assert waiting
    head = tuple(world.roadways.place(B).queue[0])
    assert waiting[-1][1].current == head and waiting[-1][1].stop_at_current
    # r0 releases B only after its visit, once more than 5 m from B's point; then r1 gets it.
    handover = next(i for i, (_, q, _, _) in enumerate(b_queue) if q.holder == "r1")
    t_release, _, positions, _ = b_queue[handover]
    assert t_release > r0.visits[0].time
    assert world.distance(positions, 0, B) > 5.0
    assert world.distance(b_queue[handover - 2][2], 0, B) <= 5.0 + 0.3
    assert r1.visits[0].time > t_release
    # Done robots release their rooms: all queues empty at the end.
    _, final, _, targets = world.log[-1]
    assert all(q.holder is None and not q.waiting for q in final.rooms)
    assert not any(target.active for target in targets)


def test_more_robots_than_slots_wait_back_from_the_tail_slot():
    world = World([C] * 5, fixed(*[[B]] * 5))
    world.run(until=70)
    times = [world.progress(i).visits[0].time for i in range(5)]
    assert times == sorted(times) and len(set(times)) == 5
    place = world.roadways.place(B)
    tail = tuple(map(float, place.queue[-1]))
    full = [(q, targets) for _, state, _, targets in world.log
            if len((q := state.room(B)).waiting) == 4]
    assert full
    queue, targets = full[-1]
    slots = [targets[int(robot[1:])].current for robot in queue.waiting]
    # The fourth 1 m (overflow_spacing) back from the tail slot towards the approach node
    # (N20, 2 m east of it), not on the third robot at the tail slot.
    assert slots == [tuple(map(float, place.queue[k])) for k in (0, 1)] + [
        tail, (tail[0] + 1.0, tail[1])]


def test_more_robots_than_slots_wait_on_the_overflow_spots_where_given():
    # The importer gives a location overflow spots where those on the line to the approach
    # node would stand in an obstacle: the fourth robot waits on the first, not on the line.
    world = World([C] * 5, fixed(*[[B]] * 5), overflow=[(3.0, 3.5)])
    world.run(until=70)
    place = world.roadways.place(B)
    full = [(q, targets) for _, state, _, targets in world.log
            if len((q := state.room(B)).waiting) == 4]
    assert full
    queue, targets = full[-1]
    slots = [targets[int(robot[1:])].current for robot in queue.waiting]
    assert slots == [tuple(map(float, place.queue[k])) for k in (0, 1, 2)] + [(18.0, 3.5)]


def plan(*stops) -> FleetPlan:
    return FleetPlan((RobotPlan("r0", tuple(Stop(k, loc) for k, loc in stops)),))


def test_plan_change_keeps_the_common_prefix():
    unchanged = World([A], ScriptedPlan([(0.0, plan(("k1", B), ("k2", C)))]))
    unchanged.run(until=70)
    first_b = unchanged.progress(0).visits[0]
    assert (first_b.key, first_b.location) == ("k1", B)

    # Mid-leg (on the eastbound lane) the rest of the plan changes, its first stop does not.
    changed = World([A], ScriptedPlan([
        (0.0, plan(("k1", B), ("k2", C))),
        (12.0, plan(("k1", B), ("k3", A))),
        # After k1 is done it reappears first: never redone.
        (first_b.time + 3.0, plan(("k1", B), ("k3", A))),
    ]))
    changed.run(until=first_b.time + 40)
    visits = changed.progress(0).visits
    assert [(v.key, v.location) for v in visits] == [("k1", B), ("k3", A)]
    assert visits[0].time == first_b.time


def test_plan_change_mid_leg_reroutes_from_the_next_node():
    world = World([A], ScriptedPlan([(0.0, plan(("k1", B))), (12.0, plan(("k9", C)))]))
    world.run(until=12.0)
    _, _, positions, targets = world.log[-1]
    assert targets[0].current == (10.0, 0.0) and positions[0][0] < 10.0  # eastbound lane
    world.run(until=60.0)
    progress = world.progress(0)
    assert [(v.key, v.location) for v in progress.visits] == [("k9", C)]
    # It went on east to C, never to B's queue: by the lanes from S10 on.
    b = world.roadways.place(B)
    b_points = {tuple(map(float, p)) for p in (*b.queue, *b.entry, b.point)}
    currents = [targets[0].current for _, _, _, targets in world.log]
    assert not b_points & set(currents)
    after = list(dict.fromkeys(currents[currents.index((10.0, 0.0)):]))
    assert after[:4] == [(10.0, 0.0), (20.0, 0.0), (30.0, 0.0), (30.0, 1.5)]
    assert progress.visits[0].time < 12.0 + 35.0


def test_a_robot_without_stops_is_inactive():
    world = World([A], fixed([]))
    world.run(until=1.0)
    _, state, positions, targets = world.log[-1]
    assert not targets[0].active
    np.testing.assert_allclose(positions[0], world.roadways.place(A).point)
    assert world.progress(0).visits == ()


def test_outputs_stay_the_same_objects_while_the_state_does():
    # Consumers (planner, recorder, queues) may skip work on an unchanged payload by identity.
    world = World([A], fixed([]))
    world.run(until=1.0)
    first, *rest = [targets[0] for _, _, _, targets in world.log]
    assert rest and all(target is first for target in rest)


def test_a_stop_where_the_robot_stands_is_served_in_place():
    # No start_location: the robot is known to be at A by standing on its point.
    world = World([A], fixed([A, B]), start_known=False, params=WaypointParams(service_time=3.0))
    world.run(until=75.0)
    visits = world.progress(0).visits
    assert [(v.key, v.location) for v in visits] == [("r0/visit0", A), ("r0/visit1", B)]
    assert 3.0 <= visits[0].time <= 3.5  # request, grant, then 3 s standing there
    # It then leaves A by its door, on A's leg to B.
    currents = [targets[0].current for t, _, _, targets in world.log if t > visits[0].time]
    assert currents[0] == (5.0, 2.5)


def test_a_robot_done_at_a_room_parks_off_the_point_and_frees_the_room():
    world = World([C, C], fixed([B], [A, B]), parking=True)
    world.run(until=90.0)
    r0, r1 = world.progress(0), world.progress(1)
    assert [v.location for v in r0.visits] == [B]
    assert [v.location for v in r1.visits] == [A, B]
    _, final, positions, targets = world.log[-1]
    # Both wait on B's parking spots, off its point: r0 on the first, r1 on the second.
    np.testing.assert_allclose(positions, world.roadways.place(B).parking, atol=1e-6)
    assert [t.current for t in targets] == [(17.0, 5.0), (17.0, 6.5)]
    # r0 released B once it had left the point, before r1 came for it; r1 released it too.
    handover = [t for t, q, _, _ in world.log if q.room(B).holder == "r1"]
    assert handover and handover[0] < r1.visits[1].time
    assert final.room(B).holder is None


def test_without_parking_a_robot_done_at_a_room_stays_on_the_point_and_frees_the_room():
    world = World([C], fixed([B]), params=WaypointParams(parking=False), parking=True)
    world.run(until=60.0)
    assert [v.location for v in world.progress(0).visits] == [B]
    _, final, positions, targets = world.log[-1]
    assert world.distance(positions, 0, B) < 1.0
    assert not targets[0].active
    assert final.room(B).holder is None


def test_a_robot_done_at_a_room_without_parking_drives_back_to_its_start_spot():
    # r0 starts on the eastbound lane, off every location, and serves B, which has no
    # parking spot: it leaves B's point (freeing the room) along the lanes, back home.
    home = (10.0, 0.0)
    world = World([None], fixed([B]), start_known=False, homes=[home])
    world.run(until=120.0)
    assert [v.location for v in world.progress(0).visits] == [B]
    served = world.progress(0).visits[0].time
    _, final, positions, targets = world.log[-1]
    np.testing.assert_allclose(positions[0], home, atol=0.05)
    assert targets[0].active and targets[0].stop_at_current and targets[0].current == home
    assert final.room(B).holder is None
    # Out along the lanes: never through the rooms' walls between B's point and home.
    after = [p[0] for t, _, p, _ in world.log if t > served]
    assert min(p[1] for p in after) >= -0.05 and max(p[0] for p in after) <= 30.05
    # Without a home (a robot that started on a location), it stays by the point.
    stays = World([C], fixed([B]), parking=False)
    stays.run(until=60.0)
    _, _, positions, targets = stays.log[-1]
    assert stays.distance(positions, 0, B) < 1.0 and not targets[0].active


def test_a_robot_done_at_a_room_whose_parking_spots_are_taken_drives_home():
    # Three robots serve B, which has two parking spots: the first two park there, the
    # third finds both taken and drives back home (before, it stood beside the point: on
    # battle_royale, seed 2, four robots so piled in goal_A's corner for 30-37 s).
    homes = [(10.0, 0.0), (20.0, 0.0), (0.0, 0.0)]
    world = World([None] * 3, fixed([B], [B], [B]), start_known=False, parking=True,
                  homes=homes)
    world.run(until=150.0)
    assert all([v.location for v in world.progress(i).visits] == [B] for i in range(3))
    _, final, positions, _ = world.log[-1]
    spots = world.roadways.place(B).parking
    parked = [min(np.linalg.norm(np.subtract(p, spot)) for spot in spots) < 1e-6
              for p in positions]
    at_home = [np.linalg.norm(np.subtract(p, home)) < 0.05
               for p, home in zip(positions, homes, strict=True)]
    assert sum(parked) == 2 and sum(at_home) == 1 and not any(np.logical_and(parked, at_home))
    assert final.room(B).holder is None


def test_a_robot_without_a_home_whose_parking_spots_are_taken_parks_at_a_free_one_elsewhere():
    # Three robots that started on locations (no home) serve B, which has two parking
    # spots: the first two park there, the third finds both taken and drives to the
    # nearest free parking spot on the level, A's first. Before, it parked on B's last
    # spot beside the robot there (the airport terminal: up to three robots jostling
    # round one of zone_2's spots for the rest of the run).
    world = World([A, C, C], fixed([B], [B], [B]), parking=True)
    world.run(until=150.0)
    assert all([v.location for v in world.progress(i).visits] == [B] for i in range(3))
    _, final, positions, targets = world.log[-1]
    at = [[int(np.linalg.norm(np.subtract(p, spot)) < 1e-6) for p in positions]
          for spot in (*world.roadways.place(B).parking, world.roadways.place(A).parking[0])]
    assert [sum(row) for row in at] == [1, 1, 1]
    assert all(t.active for t in targets)
    assert final.room(A).holder is None and final.room(B).holder is None


def test_robots_that_chose_one_parking_spot_together_share_the_spots_out():
    # Three robots without a home stand on B's point with nothing to do: each sees B's
    # first spot free and drives there. The one nearer it (first in robot order when as
    # near) keeps it; the second takes B's other spot, the third the nearest free spot
    # on the level, A's first. Before, all three stood on B's first spot to the end (the
    # airport terminal, seed 7: two robots circling round one of zone_2's spots).
    world = World([B, B, B], fixed([], [], []), parking=True)
    world.run(until=60.0)
    _, _, positions, targets = world.log[-1]
    spots = [*world.roadways.place(B).parking, world.roadways.place(A).parking[0]]
    np.testing.assert_allclose(positions, spots, atol=1e-6)
    assert all(t.active for t in targets)


def test_a_robot_done_at_a_room_drives_home_on_its_level_though_another_robot_stands_there():
    # r1 (home at 20, 0) stands idle on r0's home (10, 0) as r0 serves B, which has no
    # parking spot: r0 drives back to its own home all the same. Before, it drove to r1's
    # free start spot instead, and stood there when r1 came home (the one-level office,
    # seed 0: 10 of 25 tasks, robots waiting at each other's start spots in the lanes).
    homes = [(10.0, 0.0), (20.0, 0.0)]
    world = World([None, None], fixed([B], []), start_known=False, homes=homes,
                  at=[homes[0], (10.3, 0.0)])
    world.run(until=120.0)
    assert [v.location for v in world.progress(0).visits] == [B]
    _, _, positions, targets = world.log[-1]
    assert targets[0].active and targets[0].current == homes[0]
    np.testing.assert_allclose(positions, [homes[0], (10.3, 0.0)], atol=0.35)


def test_a_robot_waiting_at_its_next_stops_queue_releases_the_room_it_left():
    # r0 serves A, then queues for B, which r1 holds for three stops; B's queue slots lie
    # within release_distance (30 m here) of A's point: waiting at a slot, r0 gives A back
    # all the same (before, it kept A while it queued nearby: on the office, seed 4, robot5
    # held patrol_D1 waiting at patrol_A1's queue, and the robots queueing for patrol_D1
    # gridlocked behind it to the end of the run).
    params = WaypointParams(service_time=40.0, release_distance=30.0)
    world = World([A, B], fixed([A, B], [B, B, B]), params=params)
    world.run(until=100.0)
    _, queues, positions, _ = world.log[-1]
    assert [v.location for v in world.progress(0).visits] == [A]
    assert queues.room(B).holder == "r1" and "r0" in queues.room(B).waiting
    slots = world.roadways.place(B).queue
    assert min(np.linalg.norm(slots - positions[0], axis=1)) < 0.05
    assert queues.room(A).holder is None


def fleet(*routes) -> FleetPlan:
    """Robot ``r<i>`` gets the stops ``routes[i]`` ((key, location) pairs)."""
    return FleetPlan(tuple(RobotPlan(f"r{i}", tuple(Stop(k, loc) for k, loc in stops))
                           for i, stops in enumerate(routes)))


def test_a_robot_parked_in_a_room_waits_for_the_holder_before_serving_there():
    # r0 serves B and parks beside its point; r1 then comes to B and stands on its point for
    # 10 s. Meanwhile r0 is given another stop at B: it must not drive onto r1.
    params = WaypointParams(service_time=10.0)
    first = [(0.0, fleet([("a", B)], [("b", A), ("c", B)]))]
    alone = World([C, C], ScriptedPlan(first), params=params, parking=True)
    alone.run(until=120.0)
    serving = [t for t, q, positions, _ in alone.log
               if q.room(B).holder == "r1" and alone.distance(positions, 1, B) < 0.1]
    assert serving, "r1 never stood on B's point holding it"
    again = serving[0] + 1.0
    world = World([C, C], ScriptedPlan(first + [(again, fleet(
        [("a", B), ("d", B)], [("b", A), ("c", B)]))]), params=params, parking=True)
    world.run(until=again + 40.0)
    while_held = [(positions, targets) for t, q, positions, targets in world.log
                  if again + 0.2 <= t and q.room(B).holder == "r1"]
    assert while_held
    # r0 stands where it parked (no target) while r1 holds the room ...
    assert all(not targets[0].active for _, targets in while_held)
    assert all(world.distance(positions, 0, B) > 1.5 for positions, _ in while_held)
    # ... then gets the room and serves its second stop at B.
    assert [v.key for v in world.progress(0).visits] == ["a", "d"]


def at_b(queue: RoomQueue | QueueState, drive: _Drive, params: WaypointParams | None = None,
         spots=()):
    """Robot r0 alone (of two) in state ``drive`` (its stop at B), with B's ``queue`` (or
    the whole ``QueueState``) and the start ``spots``: (generator, context, B's place)."""
    roadways = loop_world(parking=True)
    generator = WaypointGenerator(["r0", "r1"], 0, roadways, A, params or WaypointParams(),
                                  None, spots, rate_hz=10.0)
    context = generator.CreateDefaultContext()
    generator.GetInputPort("plan").FixValue(context, plan(("a", B)))
    generator.GetInputPort("queue_state").FixValue(
        context, queue if isinstance(queue, QueueState) else QueueState((queue,)))
    context.SetAbstractState(0, drive)
    return generator, context, roadways.place(B)


def test_a_robot_parked_at_one_room_gives_back_another_it_holds():
    # r0 parked on B's second spot with nothing to do, still holding A and standing by A's
    # point: it is not parked at A (its spot index is B's), so it gives A back.
    generator, context, _ = at_b(RoomQueue(A, holder="r0"), _Drive(
        phase=RobotMode.PARK, stop=None, index=1, last_location=B))
    generator.GetInputPort("plan").FixValue(context, FleetPlan(()))
    stepper(generator, context, loop_world(parking=True).place(A).point)((20.0, 0.0), 0.0)
    assert generator.GetOutputPort("queue_request").Eval(context).release == A


def queueing_at_b(queue: RoomQueue | QueueState, slot: int,
                  params: WaypointParams | None = None, spots=()):
    """Robot r0 alone (of two), in the queue phase for its stop at B at ``slot``, with B's
    ``queue``: (generator, context, B's place)."""
    return at_b(queue, _Drive(phase=RobotMode.QUEUE, stop=Stop("a", B), index=slot,
                              last_location=A), params, spots)


def stepper(generator, context, r0_xy):
    """``step(r1_xy, r1_speed)``: r0 standing at ``r0_xy`` and r1 there, one update; r0's
    target after it."""
    simulator = Simulator(generator, context)

    def step(r1_xy, r1_speed):
        generator.GetInputPort("robot_state").FixValue(
            context, [*r0_xy, 0.0, 0.0, *r1_xy, -1.57, r1_speed])
        simulator.AdvanceTo(context.get_time() + 0.1)
        return generator.GetOutputPort("target").Eval(context)

    return step


def test_a_holder_waits_at_its_slot_while_another_robot_moves_in_the_doorway():
    # r0 queues first at B's door slot; r1, who had parked in B, drives out through the door
    # just as r0 is granted B. Entering then would stand both in the doorway.
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r0"), slot=0)
    slot = place.queue[0]
    step = stepper(generator, context, slot)
    entry = place.entry[0]
    # r1 moving 0.6 m from the entry: r0 keeps to its slot, tick after tick.
    assert step((entry[0], entry[1] + 0.6), 0.5).current == tuple(slot)
    assert step((entry[0] - 0.6, entry[1] - 0.2), 0.5).current == tuple(slot)
    # r1 stopping there, in the doorway, holds it too: the two could not pass.
    assert step((entry[0] - 0.6, entry[1] - 0.2), 0.0).current == tuple(slot)
    # r1 out of the way: r0 goes in.
    assert step((entry[0] - 5.0, entry[1] - 1.0), 0.5).current == tuple(entry)


def test_a_holder_waiting_at_its_door_names_the_robots_standing_in_its_doorway():
    # The deadlock watchdog's cycles of waits see whom a holder waits for at its door
    # (QueueRequest.door): r1 standing between B's first slot and its entry point.
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r0"), slot=0)
    step = stepper(generator, context, place.queue[0])
    step((15.5, 2.0), 0.0)
    assert generator.GetOutputPort("queue_request").Eval(context).door == ("r1",)
    step((15.5 - 5.0, 1.0), 0.0)  # out of the doorway: r0 enters, waiting for nobody
    assert generator.GetOutputPort("queue_request").Eval(context).door == ()


def driving_into_b(lanes: Need = NOTHING):
    """r0, holding B, driving in past slot 1 (holding single-file ``lanes``): its stepper,
    B's place, and a point in B's doorway between its door and point."""
    place = loop_world(parking=True).place(B)
    route = tuple(tuple(map(float, xy)) for xy in [*place.queue[1::-1], *place.entry,
                                                    place.point])
    generator, context, place = at_b(RoomQueue(B, holder="r0"), _Drive(
        phase=RobotMode.ENTER, stop=Stop("a", B), route=route, last_location=A,
        lanes=lanes))
    step = stepper(generator, context, (place.queue[1][0] + 0.6, place.queue[1][1]))
    return step, place, (place.entry[0][0], place.entry[0][1] + 1.2)


def test_a_holder_driving_in_stops_at_a_slot_while_another_robot_stands_in_the_doorway():
    # Soak seed 115 (issue 15): robot2, granted room_1 on its way there, drove through the
    # queue slots into the door while robot6, on its way out, stood in it, and squeezed past
    # it 2.4 cm from the jamb. r0 here holds B and drives in from slot 1; r1 stands
    # between B's door and point.
    step, place, in_door = driving_into_b()
    # r0 stops at slot 1, the slot ahead of it, rather than drive on into the door ...
    stop = WaypointTarget("r0", True, tuple(place.queue[1]), None, True)
    assert step(in_door, 0.0) == stop
    # ... and waits there while r1 stands and then drives out through the door ...
    assert step(in_door, 0.0) == stop
    assert step(tuple(place.entry[0]), 0.5) == stop
    # ... then drives in (slot 1 reached: on to slot 0).
    assert step((10.0, 1.5), 0.5).current == tuple(place.queue[0])


def test_a_holder_driving_in_on_single_file_segments_stands_where_it_is():
    # The office demo, seed 0: a holder stopped by the doorway went back to the queue phase,
    # gave up the single-file segments of its way in, and the robots behind it took them
    # (a gridlock). Holding segments of its way in, it stands where it is instead.
    step, _, in_door = driving_into_b(Need(((0, True),)))
    assert not step(in_door, 0.0).active  # standing, not back to slot 1


def test_a_holder_does_not_wait_for_the_robots_that_wait_for_it_or_stand_for_good():
    # Each of these stands in B's doorway yet is no reason to wait (it would deadlock): on
    # the point to serve there after r0, in B's queue, waiting for single-file segments,
    # broken down, or at its start spot.
    door = (15.5, 2.0)  # between B's first slot and its entry point
    cases = [
        (RoomQueue(B, holder="r0"), (15.0, 4.3), Disturbances(), ()),
        (RoomQueue(B, holder="r0", waiting=("r1",)), door, Disturbances(), ()),
        (QueueState((RoomQueue(B, holder="r0"),), segment_waiting=("r1",)), door,
         Disturbances(), ()),
        (RoomQueue(B, holder="r0"), door, Disturbances(breakdowns=(Breakdown(1, 0.0),)), ()),
        (RoomQueue(B, holder="r0"), door, Disturbances(), (door,)),
    ]
    for queue, r1_xy, disturbances, spots in cases:
        generator, context, place = queueing_at_b(queue, slot=0, spots=spots)
        generator.GetInputPort("disturbances").FixValue(context, disturbances)
        step = stepper(generator, context, place.queue[0])
        assert step(r1_xy, 0.0).current == tuple(place.entry[0])
    # The same spot without any of these: r0 waits.
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r0"), slot=0)
    assert stepper(generator, context, place.queue[0])(door, 0.0).current == \
        tuple(place.queue[0])


def test_a_holder_enters_after_door_patience_and_keeps_going():
    # r1 stands in the doorway for good (e.g. stuck): r0 waits door_patience, then drives in
    # as without the wait, and does not stop again before the door.
    params = WaypointParams(door_patience=2.0)
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r0"), slot=1,
                                              params=params)
    step = stepper(generator, context, (place.queue[1][0] + 1.2, place.queue[1][1]))
    door = (15.5, 2.0)
    targets = [step(door, 0.0) for _ in range(40)]  # 4 s
    wait = WaypointTarget("r0", True, tuple(place.queue[1]), None, True)
    go = WaypointTarget("r0", True, tuple(place.queue[1]), tuple(place.queue[0]), False)
    waited = targets.index(go)
    assert 1.9 <= waited * 0.1 <= 2.2
    assert targets[:waited] == [wait] * waited
    assert targets[waited:] == [go] * (len(targets) - waited)


def test_door_patience_must_be_positive():
    with pytest.raises(InputError, match="door_patience"):
        WaypointParams(door_patience=0.0)


def test_without_door_wait_the_holder_enters_while_another_robot_moves_in_the_doorway():
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r0"), slot=0,
                                              params=WaypointParams(door_wait=False))
    entry = place.entry[0]
    generator.GetInputPort("robot_state").FixValue(
        context, [*place.queue[0], 0.0, 0.0, entry[0], entry[1] + 0.6, -1.57, 0.5])
    Simulator(generator, context).AdvanceTo(0.05)
    assert generator.GetOutputPort("target").Eval(context).current == tuple(entry)


def test_queued_robots_move_up_without_entering_while_another_holds_the_room():
    # The door rule only holds back the holder: a robot waiting behind it still moves up.
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r1", waiting=("r0",)),
                                              slot=2)
    generator.GetInputPort("robot_state").FixValue(
        context, [*place.queue[2], 0.0, 0.0, *place.point, 0.0, 0.5])
    Simulator(generator, context).AdvanceTo(0.05)
    assert generator.GetOutputPort("target").Eval(context).current == tuple(place.queue[0])


def test_the_first_robot_waiting_keeps_a_slot_back_while_the_holder_stands_at_the_head():
    # r1 holds B and stands at the head slot (waiting there for its way in): r0, first in
    # the queue, waits at the next slot, not in r1's way in (office seed 2: coe's holder
    # boxed in at its one slot); once r1 is in, r0 moves up.
    generator, context, place = queueing_at_b(RoomQueue(B, holder="r1", waiting=("r0",)),
                                              slot=2)
    simulator = Simulator(generator, context)
    for r1_xy, slot in ((place.queue[0], 1), (place.point, 0)):
        generator.GetInputPort("robot_state").FixValue(
            context, [*place.queue[2], 0.0, 0.0, *r1_xy, 0.0, 0.0])
        simulator.AdvanceTo(context.get_time() + 0.1)
        assert generator.GetOutputPort("target").Eval(context).current == \
            tuple(place.queue[slot])


class _Inputs:
    """What ``WaypointPolicy.update`` reads, fixed: time ``t`` (s), an empty plan,
    ``queues``, no disturbances, ``states`` (N, 4), no lifts and the watchdog's
    ``back_offs``."""

    def __init__(self, t, queues, states, back_offs=NO_BACK_OFFS):
        self.t, self.queues, self.states = t, queues, np.asarray(states, dtype=float)
        self.plan, self.disturbances, self.lifts = FleetPlan(()), NO_DISTURBANCES, LiftState()
        self.back_offs = back_offs


def spur_world() -> Roadways:
    """A corridor W (0, 0) - J (10, 0) - E (20, 0) with a spur J - S (10, 5), every lane
    single file (segments W-J 0, J-E 1, J-S 2); location A beside the corridor."""
    nodes = {"W": [0.0, 0.0], "J": [10.0, 0.0], "E": [20.0, 0.0], "S": [10.0, 5.0]}
    pairs = [("W", "J"), ("J", "E"), ("J", "S")]
    edges = [[a, b] for a, b in pairs] + [[b, a] for a, b in pairs]
    locations = [LocationConfig(id=0, name="A", point=[14.0, 1.5], queue=[[12.6, 1.5]],
                                exit_node="J", approach_node="J")]
    return Roadways(RoadwaysConfig(nodes=nodes, edges=edges,
                                   single_file=[["W", "J"], ["J", "E"], ["J", "S"]]),
                    locations)


def test_a_robot_back_home_holds_only_the_segment_it_stands_in():
    # Driving home from W to the spur's end S it holds the run W-J-S; once home, only the
    # spur it stands in (before, it kept the corridor W-J to the end: on the office, seed 4,
    # a robot home beside patrol_A2 held four segments of its way back, and three robots
    # waited for one of them from 31 to 83 s).
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams(), home=(10.0, 5.0))
    route = ((0.0, 0.0), (10.0, 0.0), (10.0, 5.0))
    held = QueueState(segments=(SegmentHold(("r0",), True),) * 3)
    s = _Drive(phase=RobotMode.HOME, route=route, index=2)
    driving = policy.update(s, _Inputs(10.0, held, [[10.0, 3.0, 0.0, 0.5]]))
    assert [k for k, _ in driving.lanes.segments] == [0, 2]
    home = policy.update(s, _Inputs(10.0, held, [[10.0, 4.9, 0.0, 0.0]]))
    assert home.lanes == Need(((2, True),), stops=(2,), standing=(2,))  # it stands in it


def test_a_robot_without_a_stop_holds_the_segment_it_stands_in():
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams())
    idle = policy.update(policy.initial_state(),
                         _Inputs(1.0, QueueState(segments=(SegmentHold(),) * 3),
                                 [[10.0, 4.0, 0.0, 0.0]]))
    assert idle.phase == RobotMode.IDLE
    assert idle.lanes == Need(((2, True),), stops=(2,), standing=(2,))


def test_a_robot_without_a_stop_leaves_a_segment_another_robot_waits_for_away_from_it():
    # r0 stands idle in the spur J-S, which r1, at W, waits for: r0 drives out of the spur
    # and on to E, the one spot in no segment r1 waits for or another robot holds (W, by
    # r1, is taken). With r1 at E instead, r0 leaves for W.
    policy = WaypointPolicy(["r0", "r1"], 0, spur_world(), None, WaypointParams())
    wanted = QueueState(segments=(SegmentHold(), SegmentHold(),
                                  SegmentHold(("r0",), True, ("r1",))))
    s = policy.initial_state()
    east = policy.update(s, _Inputs(1.0, wanted, [[10.0, 4.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]))
    assert east.phase == RobotMode.HOME and east.route == ((10.0, 0.0), (20.0, 0.0))
    # It asks for J-E and keeps the spur it drives out of, the way out, until at J.
    assert east.lanes.segments == ((1, True), (2, False))
    west = policy.update(s, _Inputs(1.0, wanted, [[10.0, 4.0, 0.0, 0.0], [20.0, 0.0, 0.0, 0.0]]))
    assert west.route == ((10.0, 0.0), (0.0, 0.0))
    # Nobody waits: it stays.
    free = QueueState(segments=(SegmentHold(),) * 2 + (SegmentHold(("r0",), True),))
    assert policy.update(s, _Inputs(1.0, free, [[10.0, 4.0, 0.0, 0.0],
                                                 [0.0, 0.0, 0.0, 0.0]])).phase == RobotMode.IDLE


def test_a_robot_without_a_stop_does_not_leave_towards_the_robot_that_needs_its_segment():
    # r0 idle in the corridor W-J, 2 m from J; r1, holding W-J, drives in from W: r0
    # leaves by J, away from r1 (to S, the nearest spot off W-J), not by W.
    policy = WaypointPolicy(["r0", "r1"], 0, spur_world(), None, WaypointParams())
    held = QueueState(segments=(SegmentHold(("r1",), True), SegmentHold(), SegmentHold()))
    s = policy.update(policy.initial_state(),
                      _Inputs(1.0, held, [[8.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.5]]))
    assert s.phase == RobotMode.HOME and s.route == ((10.0, 0.0), (10.0, 5.0))


def corridor_world() -> Roadways:
    """The corridor W (0, 0) - M (5, 0) - J (10, 0), one single-file segment (0), with
    J - E (20, 0) (1) and the spur J - S (10, 5) (2); location A's queue slot 0.6 m from S."""
    nodes = {"W": [0.0, 0.0], "M": [5.0, 0.0], "J": [10.0, 0.0], "E": [20.0, 0.0],
             "S": [10.0, 5.0]}
    pairs = [("W", "M"), ("M", "J"), ("J", "E"), ("J", "S")]
    edges = [[a, b] for a, b in pairs] + [[b, a] for a, b in pairs]
    locations = [LocationConfig(id=0, name="A", point=[14.0, 5.0], queue=[[10.6, 5.0]],
                                exit_node="J", approach_node="J")]
    return Roadways(RoadwaysConfig(nodes=nodes, edges=edges, single_file=[
        ["W", "M", "J"], ["J", "E"], ["J", "S"]]), locations)


def test_a_robot_without_a_stop_with_no_other_refuge_waits_by_a_queue_slot():
    # The corridor W - M - J (one segment, 0) with J - E (1) and the spur J - S (2), A's
    # queue slot 0.6 m from S. r0 idle at M; r1, holding W-M-J and J-E, drives in from W:
    # r0 must leave by J, and every spot but S is in a segment r1 holds. S, by the slot,
    # is the only refuge: r0 drives there rather than stand in r1's way for good (office
    # seed 26: robot5 at v57, the dead end v62 0.79 m from coe's queue slot, 207 s).
    world = corridor_world()
    policy = WaypointPolicy(["r0", "r1"], 0, world, None, WaypointParams())
    held = QueueState(segments=(SegmentHold(("r0", "r1"), True), SegmentHold(("r1",), True),
                                SegmentHold()))
    s = policy.update(policy.initial_state(),
                      _Inputs(1.0, held, [[5.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.5]]))
    assert s.phase == RobotMode.HOME and s.route == ((10.0, 0.0), (10.0, 5.0))
    # At J, an end of the corridor (a junction or a room: r1 may get past it there), r0
    # is not boxed in: S, by the slot, is no refuge for it, and it stays.
    at_end = policy.update(policy.initial_state(),
                           _Inputs(1.0, held, [[10.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.5]]))
    assert at_end.phase == RobotMode.IDLE
    # With A's slot beside S taken, S is no refuge: r0 stays (the watchdog's business).
    policy = WaypointPolicy(["r0", "r1", "r2"], 0, world, None, WaypointParams())
    taken = policy.update(policy.initial_state(), _Inputs(
        1.0, held, [[5.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.5], [10.6, 5.0, 0.0, 0.0]]))
    assert taken.phase == RobotMode.IDLE


def test_a_robot_held_back_gives_up_the_segments_of_its_run_it_does_not_stand_in():
    # r0 drives from beside the corridor (A's point) onto J-E at E, then E - J - W: one
    # run, J-E and W-J. Holding J-E (kept from serving at A) but not W-J (x holds it), it
    # stands 1.5 m off the lanes: it gives J-E up, then waits for both (office seed 6:
    # keeping it, it held back the robot that stood in W-J's place and waited for J-E).
    # Standing in J-E, it keeps it. Its route ends at W: it stops in W-J.
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams())
    route = ((14.0, 1.5), (20.0, 0.0), (10.0, 0.0), (0.0, 0.0))
    s = _Drive(phase=RobotMode.HOME, route=route, index=1)
    part = QueueState(segments=(SegmentHold(("x",), True), SegmentHold(("r0",), False),
                                SegmentHold()))
    beside = policy.update(s, _Inputs(10.0, part, [[13.5, 1.5, 0.0, 0.0]]))
    assert beside.lanes == Need(((0, False),), hold=True, stops=(0,))
    none = QueueState(segments=(SegmentHold(("x",), True), SegmentHold(), SegmentHold()))
    again = policy.update(beside, _Inputs(10.1, none, [[13.5, 1.5, 0.0, 0.0]]))
    assert again.lanes == Need(((0, False), (1, False)), hold=True, stops=(0,))
    inside = policy.update(s, _Inputs(10.0, part, [[15.0, 0.2, 0.0, 0.0]]))
    assert inside.lanes == Need(((0, False), (1, False)), hold=True, stops=(0,))


def test_a_robot_held_back_whose_missing_segments_are_free_keeps_those_it_holds():
    # As above, but no other robot holds W-J: r0 asks for the whole run at once, keeping
    # J-E, and likewise holding W-J but not J-E. Before, it gave J-E up and asked for W-J
    # alone, was granted it, gave it up for J-E, and so on every update, standing (the
    # campus, seed 10: robot1, served 0.58 m off room_3's point and so standing in no
    # segment, held its two segments in turn from 262 s to the end; 10 of 18 tasks).
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams())
    route = ((14.0, 1.5), (20.0, 0.0), (10.0, 0.0), (0.0, 0.0))
    s = _Drive(phase=RobotMode.HOME, route=route, index=1)
    whole = Need(((0, False), (1, False)), hold=True, stops=(0,))
    for held in (1, 0):
        queues = QueueState(segments=tuple(SegmentHold(("r0",) if k == held else (), False)
                                           for k in range(3)))
        assert policy.update(s, _Inputs(10.0, queues, [[13.5, 1.5, 0.0, 0.0]])).lanes == whole


def test_a_robot_never_given_a_stop_drives_back_to_its_start_spot_off_the_lanes():
    # r0 starts between the two lanes, off the locations, with nothing to do, and stands
    # 2 m from its start spot (as when a robot driving past pushes it away): it drives
    # back (before, idle with its target inactive, it stood where it was pushed: triple_H
    # seed 1, onto a corridor's lane). r1, whose start spot is on a lane, stays idle where
    # it stands, off that lane.
    homes = [(10.0, 0.75), (20.0, 0.0)]
    world = World([None, None], fixed([], []), start_known=False, homes=homes,
                  at=[(12.0, 1.5), (20.0, -1.0)])
    world.run(until=5.0)
    _, _, positions, targets = world.log[-1]
    assert targets[0].active and targets[0].stop_at_current and targets[0].current == homes[0]
    np.testing.assert_allclose(positions[0], homes[0], atol=0.05)
    assert not targets[1].active
    np.testing.assert_allclose(positions[1], (20.0, -1.0))


def test_a_start_spot_on_a_lane_is_within_on_lane_of_it():
    roadways = loop_world()
    assert roadways.distance_to_lanes((10.0, 0.75)) == pytest.approx(0.75)
    assert roadways.distance_to_lanes((12.0, 0.0)) == 0.0
    assert roadways.distance_to_lanes((-1.0, -1.0)) == pytest.approx(math.sqrt(2.0))
    with pytest.raises(InputError, match="on_lane"):
        WaypointParams(on_lane=0.0)


def test_a_robot_held_back_keeps_the_segment_it_holds_and_stands_in_off_its_route():
    # r0, 1 m up the spur J-S (segment 2, which it holds northbound-out: S -> J), given a
    # way west from J that it counts as begun (driving to W); x holds W-J. Held back, it
    # keeps the spur it stands in: before, it asked for W-J alone, gave the spur up, and
    # a robot granted it drove in head-on (office seed 9: five robots stood ~180 s).
    policy = WaypointPolicy(["r0"], 0, spur_world(), None, WaypointParams())
    s = _Drive(phase=RobotMode.HOME, route=((10.0, 0.0), (0.0, 0.0)), index=1)
    queues = QueueState(segments=(SegmentHold(("x",), True), SegmentHold(),
                                  SegmentHold(("r0",), False)))
    held_back = policy.update(s, _Inputs(10.0, queues, [[10.0, 1.0, -math.pi / 2, 0.0]]))
    assert held_back.lanes == Need(((0, False), (2, False)), hold=True, stops=(0,))
    # At J, where the segments meet, only its route's, as before.
    at_j = policy.update(s, _Inputs(10.0, queues, [[10.0, 0.3, -math.pi / 2, 0.0]]))
    assert at_j.lanes == Need(((0, False),), hold=True, stops=(0,))
    # Not holding the spur, it does not ask for it (it waits for W-J as before).
    free = QueueState(segments=(SegmentHold(("x",), True), SegmentHold(), SegmentHold()))
    waiting = policy.update(s, _Inputs(10.0, free, [[10.0, 1.0, -math.pi / 2, 0.0]]))
    assert waiting.lanes == Need(((0, False),), hold=True, stops=(0,))


def test_where_a_robot_waits_is_kept_per_roadways_and_place_not_mixed_across_closures():
    # ``_home_spot``'s lanes searches are kept per roadways (by their closures) and place:
    # a closure that cuts the way home gives another answer, each time it is asked.
    roadways = loop_world(parking=True)
    home = (20.0, 0.0)

    def policy():
        return WaypointPolicy(["r0", "r1"], 0, roadways, B, home=home,
                              spots=[home, (0.0, 0.0)])

    closed = roadways.closed([(16.0, 18.0, -0.5, 0.5)])  # the eastbound lane S10-S20
    kept = policy()
    answers = [kept._spots_reached(roadways.place(place), lanes)
               for place in (B, A) for lanes in (roadways, closed, roadways, closed)]
    assert answers == [policy()._spots_reached(roadways.place(place), lanes)
                       for place in (B, A) for lanes in (roadways, closed, roadways, closed)]
    assert answers[0] == (True, ()) and not answers[1][0] and answers[1][1]


def test_a_robot_without_a_stop_keeps_the_whole_segment_it_drives_out_of():
    # The corridor W - M - J is one segment of two lanes. r0, idle 2 m from W, stands in
    # it; r1 at W waits for it: r0 leaves by J, two lanes on, and keeps the corridor, the
    # way to J, until there. Before, it kept only a segment whose lane it stood by ended at
    # J, so it gave the corridor up, and r1, granted it, drove in head-on (office seed 20:
    # robot3, done at patrol_B, gave up segment 16 to robot6 and drove along it to v54).
    world = corridor_world()
    policy = WaypointPolicy(["r0", "r1"], 0, world, None, WaypointParams())
    wanted = QueueState(segments=(SegmentHold(("r0",), True, ("r1",)), SegmentHold(),
                                  SegmentHold()))
    s = policy.update(policy.initial_state(),
                      _Inputs(1.0, wanted, [[2.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]))
    assert s.phase == RobotMode.HOME and s.route[0] == (10.0, 0.0)
    forward = world.segment_of((0.0, 0.0), (5.0, 0.0))[1]
    assert s.lanes.segments == ((0, forward),)  # its way on it asks for from 4 m before
