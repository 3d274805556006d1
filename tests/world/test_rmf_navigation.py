"""Navigation derived from a building level: lanes, task locations, queues, parking."""

from pathlib import Path

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.lane_derivation import (
    CentrelineEdge,
    CentrelineGraph,
    SingleFileSegment,
)
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import SingleFileParams
from mrta_drake.world.obstacles import Obstacles
from mrta_drake.world.rmf_building import load_building
from mrta_drake.world.rmf_navigation import (
    BuildingNavigationParams,
    _spaced,
    centre_lines,
    level_navigation,
    one_way_round_loops,
)
from mrta_drake.world.rmf_world import level_world

BUILDINGS = Path(__file__).parents[1] / "data" / "buildings"
LEVELS = [("one_level", "L1"), ("two_levels", "L1"), ("two_levels", "L2"),
          ("cartesian", "ground"), ("narrow_loop", "ground")]
PARAMS = BuildingNavigationParams()


def derived(name: str, level: str, params: BuildingNavigationParams = PARAMS):
    building = load_building(BUILDINGS / f"{name}.building.yaml")
    world = level_world(building, level, params.graph)
    return building, world.floor_plan, level_navigation(building, level, world.floor_plan,
                                                        params)


def test_task_locations_are_workcells_then_named_vertices():
    _, _, navigation = derived("one_level", "L1")
    names = [location.name for location in navigation.locations]
    # The dispenser and the ingestor first; the charger is where robots park, not a task.
    assert names == ["pantry", "lab", "reception", "park_1"]
    assert [location.id for location in navigation.locations] == [0, 1, 2, 3]
    for location in navigation.locations:
        assert location.exit_node == location.name
        assert location.point == navigation.roadways.nodes[location.name]


@pytest.mark.parametrize("name, level", LEVELS)
def test_every_location_reaches_every_other_along_one_way_lanes(name, level):
    _, _, navigation = derived(name, level)
    roadways = Roadways(navigation.roadways, navigation.locations, name)
    ids = roadways.location_ids
    for a in ids:
        for b in ids:
            if a != b:
                leg = roadways.leg(a, b)
                assert leg is not None and np.allclose(leg[-1], roadways.place(b).tail)


@pytest.mark.parametrize("name, level", LEVELS)
def test_no_leg_drives_the_same_point_twice(name, level):
    # Out of a location whose exit node is its point by that node's lanes: never out along
    # the entry first and back to the point (a room at the end of its entry, driven twice;
    # a point on a passage, left away from where the leg goes and back).
    _, _, navigation = derived(name, level)
    roadways = Roadways(navigation.roadways, navigation.locations, name)
    for a in roadways.location_ids:
        for b in roadways.location_ids:
            if a != b:
                points = [tuple(p) for p in roadways.leg(a, b)]
                assert len(set(points)) == len(points), (a, b)


@pytest.mark.parametrize("name, level", LEVELS)
def test_queue_slots_and_parking_spots_are_clear_of_walls(name, level):
    _, floor_plan, navigation = derived(name, level)
    obstacles = floor_plan.obstacles
    for location in navigation.locations:
        assert location.queue
        clearance = obstacles.signed_distance(np.array(location.queue))
        assert clearance.min() >= PARAMS.slot_clearance - 1e-9, location.name
        for slot in location.queue:  # outside the waypoint generator's 1 m reach
            assert np.linalg.norm(np.subtract(slot, location.point)) > 1.0
        if location.parking:
            assert obstacles.signed_distance(np.array(location.parking)).min() >= (
                PARAMS.slot_clearance - 1e-9)


def test_queue_lies_back_along_the_approach_with_its_head_on_a_holding_point():
    _, _, navigation = derived("one_level", "L1")
    nodes = navigation.roadways.nodes
    segments = [(np.array(nodes[a]), np.array(nodes[b])) for a, b in navigation.roadways.edges]

    def off_lanes(point):
        point = np.asarray(point)
        return min(np.linalg.norm(point - (a + np.clip(np.dot(point - a, b - a) / np.dot(
            b - a, b - a), 0.0, 1.0) * (b - a))) for a, b in segments)

    pantry, lab = navigation.locations[:2]
    # The lane to the pantry runs north along x = 4 through an unnamed holding point at
    # y = -4.8, 2.8 m from the point: the head slot; the others follow back along the lanes.
    assert pantry.queue[0] == [4.0, -4.8] and pantry.entry == []
    # The lab has none, and its lane through the door is single file (3.55 m, from
    # [12, -5.55]): the robots waiting stand in the corridor, the head slot 1.3 m back
    # along the lanes from that lane's start, then 1 m apart; the lane is the lab's entry.
    assert navigation.single_file[1].nodes == ("v18_0", "lab")
    assert lab.queue == [[11.6, -6.45], [10.6, -6.45], [9.6, -6.45]]
    assert lab.entry == [[12.0, -6.45], [12.0, -5.55]]
    assert lab.parking == []  # a robot parked behind the door would block the holder
    assert pantry.parking  # the pantry's queue heads on its holding point: no zone
    for location in navigation.locations:
        assert all(off_lanes(slot) < 2e-3 for slot in location.queue), location.name  # mm
        gaps = np.linalg.norm(np.diff(np.array(location.queue), axis=0), axis=1)
        assert (gaps <= PARAMS.slot_spacing + 2e-3).all() and (gaps > 0.5).all()


def _off_lanes(navigation, points) -> np.ndarray:
    """Each of ``points``' distance to the nearest lane of ``navigation``, m."""
    nodes = navigation.roadways.nodes
    lanes = [(np.array(nodes[a]), np.array(nodes[b])) for a, b in navigation.roadways.edges]
    gaps = []
    for point in np.asarray(points, dtype=float).reshape(-1, 2):
        gaps.append(min(np.linalg.norm(point - (a + np.clip(
            np.dot(point - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0) * (b - a)))
            for a, b in lanes))
    return np.array(gaps)


def test_a_location_on_a_single_file_passage_is_served_beside_it_where_there_is_room():
    # The corridor's lane is single file; desk and closet stand on it. A robot serving on
    # it would block everyone driving through: desk is served in the alcove beside it,
    # closet (no room beside it) on its vertex.
    _, floor_plan, navigation = derived("passage", "ground")
    desk, closet = navigation.locations[:2]
    assert [desk.name, closet.name] == ["desk", "closet"]
    assert _off_lanes(navigation, [desk.point])[0] >= PARAMS.slot_lane_gap - 1e-3
    assert np.linalg.norm(np.subtract(desk.point, [10.0, 0.0])) <= PARAMS.serve_reach
    assert floor_plan.obstacles.signed_distance([desk.point])[0] >= PARAMS.slot_clearance
    assert closet.point == [16.0, 0.0] == navigation.roadways.nodes["closet"]


def test_queue_slots_by_a_single_file_lane_stand_beside_every_lane():
    # A robot waiting on the corridor's lane would block robots driving through it and
    # the holder leaving: every slot of the two locations on it keeps off the lanes, and
    # clear of the other slots and the points.
    _, floor_plan, navigation = derived("passage", "ground")
    slots = [slot for location in navigation.locations[:2] for slot in location.queue]
    assert len(slots) >= 2
    assert (_off_lanes(navigation, slots) >= PARAMS.slot_lane_gap - 1e-3).all()
    assert floor_plan.obstacles.signed_distance(np.array(slots)).min() >= PARAMS.slot_clearance
    others = slots + [location.point for location in navigation.locations]
    for k, slot in enumerate(slots):
        gaps = [np.linalg.norm(np.subtract(slot, other)) for j, other in enumerate(others)
                if j != k]
        assert min(gaps) >= PARAMS.slot_spacing - 1e-3


def test_parking_spots_stay_off_the_lanes():
    _, _, navigation = derived("one_level", "L1")
    nodes = navigation.roadways.nodes
    lanes = [(np.array(nodes[a]), np.array(nodes[b])) for a, b in navigation.roadways.edges]
    for location in navigation.locations:
        for spot in location.parking:
            gaps = []
            for a, b in lanes:
                t = np.clip(np.dot(spot - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
                gaps.append(np.linalg.norm(spot - (a + t * (b - a))))
            assert min(gaps) >= PARAMS.parking_lane_gap - 1e-9


def test_one_way_lanes_stay_one_way():
    pytest.importorskip("pyproj")
    building = load_building(BUILDINGS / "wgs84.building.yaml")
    lines = centre_lines(building, building.level("L1"), 0)
    edges = {(a, b): two_way for a, b, two_way in lines.edges}
    assert edges == {("gate", "v1"): False, ("v1", "hall"): True, ("v1", "lab"): True,
                     ("lab", "gate"): False}
    _, _, navigation = derived("wgs84", "L1")
    assert ["gate", "v1"] in navigation.roadways.edges
    assert ["v1", "gate"] not in navigation.roadways.edges


def _ring_lanes(navigation):
    """The roadway lanes between the ring's vertices of narrow_loop (both ends on the ring,
    x or y at the corridor's centre line)."""
    def on_ring(name):
        x, y = navigation.roadways.nodes[name]
        return min(abs(x - 0.8), abs(x - 15.2), abs(y - 0.8), abs(y - 9.2)) < 0.05
    return {(a, b) for a, b in navigation.roadways.edges if on_ring(a) and on_ring(b)}


def test_single_file_lanes_round_a_loop_are_driven_one_way_round_it():
    # narrow_loop's corridor is single file all round: robots driving it both ways would
    # meet head-on; driven one way round, they only follow each other.
    _, _, navigation = derived("narrow_loop", "ground")
    ring = _ring_lanes(navigation)
    assert len(ring) >= 8
    assert not any((b, a) in ring for a, b in ring)
    # The dead end to the charging room is no loop: driven both ways.
    lanes = navigation.roadways.edges
    assert any(b == "dock" for _, b in lanes) and any(a == "dock" for a, _ in lanes)
    assert all("dock" in s.vertices for s in navigation.single_file)
    _, _, both_ways = derived("narrow_loop", "ground",
                              BuildingNavigationParams(circulation=False))
    assert any((b, a) in _ring_lanes(both_ways) for a, b in _ring_lanes(both_ways))
    assert len(both_ways.single_file) > 1


def test_a_loop_single_file_only_for_a_task_location_on_it_keeps_both_ways():
    # wgs84's loop gate -> v1 - lab -> gate: v1 - lab is single file only because lab, a
    # task location on a passage, is served on its vertex; two lanes would fit, so it is
    # not turned one way round the loop.
    pytest.importorskip("pyproj")
    _, _, navigation = derived("wgs84", "L1")
    assert ["lab", "v1"] in navigation.roadways.edges
    assert [s.vertices for s in navigation.single_file] == [("v1", "lab")]


def _square(one_way=()):
    nodes = {"a": (0, 0), "b": (4, 0), "c": (4, 4), "d": (0, 4), "e": (-3, 4)}
    pairs = [("a", "b"), ("b", "c"), ("c", "d"), ("d", "a"), ("d", "e")]
    return CentrelineGraph(nodes, tuple(CentrelineEdge(a, b, one_way=(a, b) in one_way)
                                        for a, b in pairs))


def test_a_loop_is_oriented_round_and_its_bridges_and_wide_lanes_stay_two_way():
    single = (SingleFileSegment(("a", "b", "c"), ()), SingleFileSegment(("c", "d"), ()),
              SingleFileSegment(("d", "e"), ()))  # d - a has two lanes
    ways = one_way_round_loops(_square(), single)
    assert set(ways) == {frozenset(p) for p in (("a", "b"), ("b", "c"), ("c", "d"))}
    way = [ways[frozenset(p)] for p in (("a", "b"), ("b", "c"), ("c", "d"))]
    assert way in ([("a", "b"), ("b", "c"), ("c", "d")], [("b", "a"), ("c", "b"), ("d", "c")])


def test_a_loop_whose_one_way_lanes_forbid_a_round_trip_is_left_two_way():
    # a -> b is one way in the file, d -> a too: orienting b - c - d against them would cut
    # a off; whichever way the search goes, every vertex still reaches every other.
    single = (SingleFileSegment(("b", "c", "d"), ()),)
    for one_way in ((("a", "b"), ("d", "a")), (("b", "a"), ("a", "d"))):
        graph = _square(one_way)
        ways = one_way_round_loops(graph, single)
        directed = {(e.a, e.b) for e in graph.edges if e.one_way} | set(ways.values())
        for e in graph.edges:
            if not e.one_way and frozenset((e.a, e.b)) not in ways:
                directed |= {(e.a, e.b), (e.b, e.a)}
        reach = {v: {v} for v in graph.nodes}
        for _ in graph.nodes:
            for a, b in directed:
                reach[a] |= reach[b]
        assert all(reach[v] == set(graph.nodes) for v in graph.nodes), ways


def test_lanes_into_a_lift_cabin_are_left_out():
    building = load_building(BUILDINGS / "two_levels.building.yaml")
    lines = centre_lines(building, building.level("L2"), 0)
    assert (10.0, -2.0) not in lines.nodes.values()
    assert (8.2, -2.0) in lines.nodes.values()


def test_a_graph_without_lanes_is_refused_with_the_graphs_there_are():
    building = load_building(BUILDINGS / "one_level.building.yaml")
    with pytest.raises(InputError, match=r"levels\.L1\.lanes: no lanes of graph 3 \(graphs "
                       r"on this level: 0\)"):
        centre_lines(building, building.level("L1"), 3)


def test_navigation_params_check_themselves():
    with pytest.raises(InputError, match="queue_slots: must be >= 1, got 0"):
        BuildingNavigationParams(queue_slots=0)
    with pytest.raises(InputError, match="head_gap: must be > 0 m"):
        BuildingNavigationParams(head_gap=-1.0)


def test_a_room_behind_a_single_file_door_queues_beyond_the_door():
    # The two-floor clinic's rooms: a 1.6 m door (a single-file lane) into a room with
    # two-way lanes and an unnamed holding point before the task point. A robot waiting at
    # the holding point would stand at the door, in the way out of the robot serving there
    # (and hold the door's segment): the queue waits in the corridor beyond the door, the
    # door and the room's lanes are the entry, and no parking spot stays in the room.
    building = load_building(Path(__file__).parents[2] / "models" / "two_floor_clinic"
                             / "two_floor_clinic.building.yaml")
    world = level_world(building, "L1", PARAMS.graph)
    navigation = level_navigation(building, "L1", world.floor_plan, PARAMS)
    nodes = navigation.roadways.nodes
    doors = [(np.array(nodes[s.nodes[0]]), np.array(nodes[s.nodes[-1]]))
             for s in navigation.single_file]
    stand = SingleFileParams().stand_distance
    for location in navigation.locations:  # every task location is in such a room
        for slot in location.queue:
            gaps = [np.linalg.norm(np.asarray(slot) - (a + np.clip(np.dot(
                np.asarray(slot) - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0) * (b - a)))
                for a, b in doors]
            assert min(gaps) > stand, (location.name, slot)
        assert 5.5 < location.queue[0][1] < 8.5, location.name  # in the corridor
        assert len(location.entry) >= 3 and location.parking == [], location.name


@pytest.mark.parametrize("name, level", LEVELS + [("open_hall", "ground"),
                                                  ("narrow_corridor", "ground"),
                                                  ("passage", "ground")])
def test_parking_spots_keep_a_slot_spacing_from_other_places(name, level):
    # A robot parked nearer a point or queue slot of another location stands in the way
    # of the robot serving or waiting there.
    _, _, navigation = derived(name, level)
    for location in navigation.locations:
        for spot in location.parking:
            others = [xy for other in navigation.locations
                      for xy in (other.point, *other.queue,
                                 *(p for p in other.parking if p is not spot))
                      if other is not location or xy is not other.point]
            gaps = np.linalg.norm(np.array(others) - np.array(spot), axis=1)
            assert gaps.min() >= PARAMS.slot_spacing - 1e-9, (location.name, spot)


def test_the_roadways_carry_their_single_file_segments():
    # The import sizes the task stream on these roadways: without their single-file
    # segments a leg out of a location would take the lane where its own queue waits,
    # not the leg robots drive (the office's legs: 37 s longest instead of 50 s).
    _, _, navigation = derived("narrow_corridor", "ground")
    assert navigation.single_file
    assert navigation.roadways.single_file == [list(s.nodes) for s in navigation.single_file]
    assert Roadways(navigation.roadways, navigation.locations).segment_count == len(
        navigation.single_file)


def test_waiting_spots_beyond_a_queue_keep_clear_of_furniture():
    # printer's one slot stands in an aisle between desks; the waypoint generator's own
    # spots beyond it, 1 m apart on the line to the approach node, start inside a desk.
    # The spots written instead keep clear of walls and furniture, off the lanes, 1 m
    # apart, and end on the approach node (which is where those spots end too).
    _, floor_plan, navigation = derived("aisle", "ground")
    printer = navigation.locations[0]
    assert printer.name == "printer" and len(printer.queue) == 1
    tail = np.array(printer.queue[-1])
    approach = np.array(navigation.roadways.nodes[printer.approach_node])
    towards = (approach - tail) / np.linalg.norm(approach - tail)
    line = tail + towards * PARAMS.slot_spacing
    furniture = Obstacles(tuple(b for b in floor_plan.obstacles.boxes
                                if b.name.startswith("desk_")))
    assert furniture.signed_distance([line])[0] < 0.0
    spots = np.array(printer.overflow)
    assert np.allclose(spots[-1], approach)
    assert floor_plan.obstacles.signed_distance(spots[:-1]).min() >= PARAMS.slot_clearance
    assert (_off_lanes(navigation, spots[:-1]) >= PARAMS.slot_lane_gap - 1e-3).all()
    placed = np.vstack([tail, spots])
    gaps = np.linalg.norm(placed[:, None] - placed[None], axis=2)
    assert gaps[np.triu_indices(len(placed), 1)].min() >= PARAMS.slot_spacing - 1e-3
    assert any(note.startswith("waiting spots beyond the queues too near walls or furniture")
               for note in navigation.notes)
    # Where the line is clear, no spots are written: the waypoint generator's own apply.
    _, floor_plan, navigation = derived("one_level", "L1")
    assert all(not location.overflow for location in navigation.locations)


def test_spacing_measured_to_the_near_taken_points_only_is_the_same():
    rng = np.random.default_rng(3)
    for _ in range(200):
        spots = rng.uniform(-2.0, 2.0, (int(rng.integers(1, 40)), 2))
        taken = rng.uniform(-6.0, 6.0, (int(rng.integers(0, 30)), 2))
        taken[:3] = spots[0] + [1.0, 0.0]  # exactly the spacing off a spot
        every = np.linalg.norm(spots[:, None] - taken[None], axis=2).min(axis=1, initial=9.0)
        spaced = _spaced(spots, list(taken), 1.0)
        np.testing.assert_array_equal(spaced, every >= 1.0 - 1e-9)
