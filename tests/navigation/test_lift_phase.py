"""Waypoint generators taking robots through a lift bank between two lane loops 100 m apart
(two levels), with fake robots that the bank relocates."""

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mrta_drake.navigation.lift_bank import LiftBank, LiftParams, LiftSpec, LiftStop
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.room_queues import RoomQueues
from mrta_drake.navigation.waypoint_generator import WaypointGenerator, WaypointParams
from mrta_drake.payloads import Relocations
from mrta_drake.scenario.schema import LiftEdgeConfig, LocationConfig, RoadwaysConfig

from .test_waypoint_generator import FakeRobots, World, fixed

SHIFT = 100.0  # m between the two levels' loops
CABIN = (10.0, -3.0)  # on L1; on L2 shifted by SHIFT


def two_level_world(parking: bool = False) -> Roadways:
    """The loop of test_waypoint_generator on each level (rooms A at x = 5 on L1 and
    B at x = 25 on L2), a lift cabin south of node S10 on each, rides both ways; with
    ``parking``, a room at x = 15 on each level (ids 2 on L1, 3 on L2) with a parking spot
    2 m east of its point."""
    nodes, edges, locations = {}, [], []
    for level, dx in (("L1", 0.0), ("L2", SHIFT)):
        xs = (0, 10, 20, 30)
        nodes |= {f"{level}/S{x}": [x + dx, 0.0] for x in xs}
        nodes |= {f"{level}/N{x}": [x + dx, 1.5] for x in xs}
        nodes[f"{level}/cab"] = [CABIN[0] + dx, CABIN[1]]
        ring = ["S0", "S10", "S20", "S30", "N30", "N20", "N10", "N0", "S0"]
        edges += [[f"{level}/{a}", f"{level}/{b}"]
                  for a, b in zip(ring[:-1], ring[1:], strict=True)]
        edges += [[f"{level}/S10", f"{level}/cab"], [f"{level}/cab", f"{level}/S10"]]
        x = 5 if level == "L1" else 25
        locations.append(LocationConfig(
            id=len(locations), point=[x + dx, 5.0],
            queue=[[x + dx + 1.0, 1.5], [x + dx + 2.0, 1.5]], entry=[[x + dx, 2.5]],
            exit_node=f"{level}/N{x - 5}", approach_node=f"{level}/N{x + 5}"))
    for dx in (0.0, SHIFT) if parking else ():
        level = "L1" if dx == 0.0 else "L2"
        locations.append(LocationConfig(
            id=len(locations), point=[15 + dx, 5.0], queue=[[16 + dx, 1.5]],
            entry=[[15 + dx, 2.5]], exit_node=f"{level}/N10", approach_node=f"{level}/N20",
            parking=[[17 + dx, 5.0]]))
    rides = [LiftEdgeConfig("lift", "L1/cab", "L2/cab", "L1", "L2", 5.0),
             LiftEdgeConfig("lift", "L2/cab", "L1/cab", "L2", "L1", 5.0)]
    return Roadways(RoadwaysConfig(nodes=nodes, edges=edges, lift_edges=rides), locations)


class RelocatedRobots(FakeRobots):
    """FakeRobots that also take a ``relocations`` input, applied once per sequence."""

    def __init__(self, starts):
        super().__init__(starts)
        self._relocations = self.DeclareAbstractInputPort("relocations",
                                                          Value[object](Relocations()))
        self._seen = [0] * len(starts)

    def _move(self, context, discrete_state):
        super()._move(context, discrete_state)
        x = discrete_state.get_mutable_vector(self._state).get_value().copy()
        for k, move in enumerate(self._relocations.Eval(context).moves):
            if move is not None and move[0] > self._seen[k]:
                x[4 * k:4 * k + 3], x[4 * k + 3] = move[1], 0.0
                self._seen[k] = move[0]
        discrete_state.get_mutable_vector(self._state).SetFromVector(x)


class LiftWorld(World):
    """World's set-up with the two-level roadways and a lift bank."""

    def __init__(self, starts, plan_source, cabin_size=0.0, homes=None, parking=False):
        """``homes``: start spots (x, y) off the locations instead, one per robot (each
        robot's home; all of them its spots); ``parking``: see ``two_level_world``."""
        self.roadways = roadways = two_level_world(parking)
        self.robots = [f"r{i}" for i in range(len(starts))]
        builder = DiagramBuilder()
        plan = builder.AddSystem(plan_source)
        queues = builder.AddSystem(RoomQueues(self.robots, roadways.location_ids, rate_hz=10.0))
        fake = builder.AddSystem(RelocatedRobots(homes or [roadways.place(s).point
                                                           for s in starts]))
        lift = LiftSpec("lift", (LiftStop("L1", CABIN, 0.0, "L1/cab"),
                                 LiftStop("L2", (CABIN[0] + SHIFT, CABIN[1]), 4.0, "L2/cab")),
                        "L1", cabin_size, cabin_size)
        self.bank = builder.AddSystem(LiftBank(self.robots, [lift], LiftParams(door_time=2.0),
                                               rate_hz=10.0))
        builder.Connect(fake.GetOutputPort("state"), self.bank.GetInputPort("robot_state"))
        builder.Connect(self.bank.GetOutputPort("relocations"), fake.GetInputPort("relocations"))
        self.generators = []
        for i, (robot, start) in enumerate(zip(self.robots, starts, strict=True)):
            generator = builder.AddSystem(WaypointGenerator(
                self.robots, i, roadways, start, WaypointParams(),
                None if homes is None else homes[i], homes or (), rate_hz=10.0))
            for source, out, sink, into in (
                    (plan, "plan", generator, "plan"),
                    (fake, "state", generator, "robot_state"),
                    (queues, "queue_state", generator, "queue_state"),
                    (self.bank, "lift_state", generator, "lift_state"),
                    (generator, "lift_request", self.bank, f"request_{robot}"),
                    (generator, "target", fake, f"target_{i}"),
                    (generator, "progress", plan, f"progress_{robot}")):
                builder.Connect(source.GetOutputPort(out), sink.GetInputPort(into))
            builder.Connect(generator.GetOutputPort("queue_request"),
                            queues.get_request_input_port(robot))
            self.generators.append(generator)
        self.queues, self.fake = queues, fake
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.log = []


def test_two_robots_take_turns_in_the_lift_and_reach_the_other_level():
    world = LiftWorld([0, 0], fixed([1], [1]))
    world.run(until=150)
    for i in (0, 1):
        (visit,) = world.progress(i).visits
        assert visit.location == 1
    events = [(e.kind, e.robot) for e in world._eval(world.bank, "events")]
    assert [e for e in events if e[0] in ("board", "arrive")] == [
        ("board", "r0"), ("arrive", "r0"), ("board", "r1"), ("arrive", "r1")]
    # While r0 rides, r1 waits 3 m back from the cabin along its route (on node S10).
    assert any(targets[1].stop_at_current and np.allclose(targets[1].current, (10.0, 0.0))
               for _, _, _, targets in world.log)
    # Both end on level 2 (x beyond the gap) and the lift is free.
    _, _, positions, _ = world.log[-1]
    assert (positions[:, 0] > SHIFT - 10.0).all()
    status = world._eval(world.bank, "lift_state").lift("lift")
    assert status.riders == () and status.level == "L2"


def test_two_robots_with_the_same_trip_ride_one_cabin_together():
    world = LiftWorld([0, 0], fixed([1], [1]), cabin_size=2.5)
    world.run(until=150)
    for i in (0, 1):
        (visit,) = world.progress(i).visits
        assert visit.location == 1
    events = [(e.kind, e.robot, e.time) for e in world._eval(world.bank, "events")]
    boards = [e for e in events if e[0] == "board"]
    arrivals = [e for e in events if e[0] == "arrive"]
    assert sorted(robot for _, robot, _ in boards) == ["r0", "r1"]
    assert len(arrivals) == 2 and arrivals[0][2] == arrivals[1][2]  # one ride
    _, _, positions, _ = world.log[-1]
    assert (positions[:, 0] > SHIFT - 10.0).all()


def test_a_robot_idle_on_another_level_than_its_home_waits_at_a_start_spot_there():
    # r0 starts at its home on L1 and serves B on L2; r1 starts at its home on L2 and
    # serves A on L1. Neither location has a parking spot: each then waits at the other's
    # start spot, free and on its own level, not driving for its home across the levels
    # (on a building, a robot would stand at the lift for good, in the others' way).
    homes = [(20.0, 0.0), (20.0 + SHIFT, 0.0)]
    world = LiftWorld([None, None], fixed([1], [0]), cabin_size=2.5, homes=homes)
    world.run(until=200)
    assert [v.location for v in world.progress(0).visits] == [1]
    assert [v.location for v in world.progress(1).visits] == [0]
    _, _, positions, targets = world.log[-1]
    np.testing.assert_allclose(positions, homes[::-1], atol=0.05)
    assert all(t.active and t.current in map(tuple, homes) for t in targets)


def test_a_robot_idle_on_another_level_than_its_home_prefers_a_parking_spot_there():
    # As above, with a room on each level whose parking spot is no robot's start: each
    # robot waits there, not at the other's start spot (its owner's way home).
    homes = [(20.0, 0.0), (20.0 + SHIFT, 0.0)]
    world = LiftWorld([None, None], fixed([1], [0]), cabin_size=2.5, homes=homes,
                      parking=True)
    world.run(until=200)
    assert [v.location for v in world.progress(0).visits] == [1]
    assert [v.location for v in world.progress(1).visits] == [0]
    _, _, positions, _ = world.log[-1]
    np.testing.assert_allclose(positions, [(17.0 + SHIFT, 5.0), (17.0, 5.0)], atol=0.05)
