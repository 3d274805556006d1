"""Navigation derived from free space on small synthetic maps
(mrta_drake/navigation/navigation_derivation.py): properties every derived navigation has."""

import functools
import itertools

import networkx as nx
import numpy as np
import pytest
import yaml

from mrta_drake.navigation.location_derivation import LocationParams, NamedPoint
from mrta_drake.navigation.navigation_derivation import (
    NavigationParams,
    derive_navigation,
    write_navigation,
)
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from tests.navigation.free_space_worlds import (
    L_BEND,
    PLUS,
    carved,
    edge_clearances,
    lane_graph,
    samples,
    walls,
)

PARAMS = NavigationParams()
# Two 5 m x 6 m rooms joined by a corridor 1.3 m wide and 6 m long.
DUMBBELL = [(-8.0, -3.0, -3.0, 3.0), (3.0, 8.0, -3.0, 3.0), (-3.05, 3.05, -0.65, 0.65)]
# A corridor 2.4 m wide with a 4 m x 4 m room north of its middle, through a 1.4 m doorway.
ROOM_OFF_CORRIDOR = [(-8.0, 8.0, -1.2, 1.2), (-2.0, 2.0, 2.4, 6.5), (-0.7, 0.7, 1.0, 2.6)]

WORLDS = {
    "plus": (PLUS, [NamedPoint("north", [0.0, 6.2]), NamedPoint("south", [0.0, -6.2]),
                    NamedPoint("east", [6.2, 0.0]), NamedPoint("west", [-6.2, 0.0])]),
    "narrow": (DUMBBELL, [NamedPoint("a", [-6.0, 1.5], parking=True),
                          NamedPoint("b", [6.0, -1.5], parking=True)]),
    "l_bend": (L_BEND, [NamedPoint("south", [0.0, -6.2]), NamedPoint("east", [6.2, 0.0])]),
    "room": (ROOM_OFF_CORRIDOR, [NamedPoint("west", [-7.0, 0.0]),
                                 NamedPoint("east", [7.0, 0.0]),
                                 NamedPoint("room", [1.0, 4.5], parking=True)]),
}


@functools.cache
def derived(name: str):
    rects, points = WORLDS[name]
    grid = carved(rects)
    return name, walls(grid), points, derive_navigation(grid, points, PARAMS)


@pytest.fixture(params=sorted(WORLDS))
def world(request):
    return derived(request.param)


def configs(navigation):
    roadways = RoadwaysConfig(**navigation["roadways"])
    return roadways, [LocationConfig(**item) for item in navigation["locations"]]


def test_every_lane_keeps_clearance(world):
    _, obstacles, _, navigation = world
    roadways, _ = configs(navigation)
    clearances = edge_clearances(roadways, obstacles)
    assert min(clearances.values()) >= PARAMS.lanes.clearance


def test_every_location_reaches_every_other_along_the_lanes(world):
    _, _, points, navigation = world
    roadways, locations = configs(navigation)
    Roadways(roadways, locations)  # its own check of the same
    graph = lane_graph(roadways)
    for source, target in itertools.permutations(locations, 2):
        assert nx.has_path(graph, source.exit_node, target.approach_node), (source.name,
                                                                            target.name)
    assert [loc.name for loc in locations] == [p.name for p in points]
    assert [loc.id for loc in locations] == list(range(len(points)))


def test_queue_slots_entries_and_parking_are_clear_of_walls(world):
    _, obstacles, _, navigation = world
    roadways, locations = configs(navigation)
    safety = PARAMS.locations.wall_safety
    for loc in locations:
        slots = np.array(loc.queue)
        assert 1 <= len(slots) <= 3
        assert obstacles.signed_distance(slots).min() >= safety, loc.name
        gaps = np.linalg.norm(slots[:, None] - slots[None], axis=-1) + 9 * np.eye(len(slots))
        assert gaps.min() >= PARAMS.locations.slot_spacing - 1e-6, loc.name
        # The way in: from the approach node along the slots, the entry, to the point.
        way_in = [roadways.nodes[loc.approach_node], *loc.queue[::-1], *loc.entry, loc.point]
        line = np.concatenate([samples(a, b) for a, b in zip(way_in[:-1], way_in[1:], strict=True)])
        assert obstacles.signed_distance(line).min() >= PARAMS.lanes.clearance
        if loc.parking:
            spots = np.array(loc.parking)
            assert obstacles.signed_distance(spots).min() >= safety
            assert (np.linalg.norm(spots - loc.point, axis=1) >= 1.6 - 1e-6).all()


def test_points_are_dead_ends_with_both_lanes_meeting_on_them(world):
    _, _, points, navigation = world
    roadways, _ = configs(navigation)
    graph = lane_graph(roadways)
    for point in points:
        assert roadways.nodes[point.name] == point.point
        (into,), (out,) = graph.predecessors(point.name), graph.successors(point.name)
        assert into == out


def test_single_file_segments_where_two_lanes_do_not_fit(world):
    name, obstacles, _, navigation = world
    roadways, _ = configs(navigation)
    segments = navigation["roadways"]["single_file"]
    if name != "narrow":
        assert segments == []
        return
    (segment,) = segments
    xy = np.array([roadways.nodes[node] for node in segment])
    # Along the narrow corridor's centre-line, both ways.
    assert np.abs(xy[:, 1]).max() < 0.1 and xy[:, 0].min() < -2.0 and xy[:, 0].max() > 2.0
    edges = {tuple(edge) for edge in roadways.edges}
    for a, b in zip(segment[:-1], segment[1:], strict=True):
        assert (a, b) in edges and (b, a) in edges


def test_room_behind_a_doorway_is_its_locations_own():
    _, _, _, navigation = derived("room")
    roadways, locations = configs(navigation)
    room = next(loc for loc in locations if loc.name == "room")
    # The entry runs from the corridor through the doorway (y 1-2.6) into the room, the
    # queue waits in the corridor, and no lane but the entry's goes through the doorway.
    entry = np.array(room.entry)
    assert entry[0][1] < 1.2 and entry[-1][1] > 2.6
    assert (np.abs(np.array(room.queue)[:, 1]) < 1.2).all()
    beyond = [xy for xy in roadways.nodes.values() if xy[1] > 1.2]
    assert sorted(beyond) == sorted([*room.entry[1:], room.point])


def test_written_file_loads_as_navigation(tmp_path, world):
    _, _, _, navigation = world
    path = tmp_path / "navigation.yaml"
    write_navigation(path, navigation, "Derived for a test.\nSecond line.")
    text = path.read_text()
    assert text.startswith("# Derived for a test.\n# Second line.\n")
    content = yaml.safe_load(text)
    assert content == navigation
    roadways, locations = configs(content)
    Roadways(roadways, locations)


def test_fewer_queue_slots_when_asked():
    rects, points = WORLDS["room"]
    params = NavigationParams(locations=LocationParams(queue_slots=1))
    navigation = derive_navigation(carved(rects), points, params)
    assert [len(loc["queue"]) for loc in navigation["locations"]] == [1, 1, 1]
