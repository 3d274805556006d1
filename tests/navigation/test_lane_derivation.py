"""Tests of one-way lanes derived from centre-lines (mrta_drake/navigation/lane_derivation.py)."""

import networkx as nx
import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.clearance_field import ClearanceField
from mrta_drake.navigation.lane_derivation import (
    CentrelineEdge,
    CentrelineGraph,
    LaneParams,
    derive_lanes,
)
from mrta_drake.navigation.roadways import Roadways
from tests.navigation.free_space_worlds import (
    L_BEND,
    NARROWED,
    PLUS,
    carved,
    edge_clearances,
    lane_graph,
    walls,
)

PARAMS = LaneParams()


def derived(free_rects, nodes, edges, params=PARAMS):
    grid = carved(free_rects)
    graph = CentrelineGraph(nodes=nodes, edges=tuple(
        edge if isinstance(edge, CentrelineEdge) else CentrelineEdge(*edge) for edge in edges))
    return derive_lanes(graph, ClearanceField.from_grid(grid), params), walls(grid)


@pytest.fixture(scope="module")
def plus():
    nodes = {"c": (0.0, 0.0), "n": (0.0, 6.0), "s": (0.0, -6.0), "e": (6.0, 0.0),
             "w": (-6.0, 0.0)}
    return derived(PLUS, nodes, [("c", "n"), ("s", "c"), ("c", "e"), ("w", "c")])


def position(lanes, node) -> np.ndarray:
    return np.array(lanes.roadways.nodes[node])


def test_plus_crossing_has_two_lanes_per_arm_right_of_travel(plus):
    lanes, _ = plus
    assert lanes.single_file == () and lanes.tight == ()
    nodes = {"c": (0.0, 0.0), "n": (0.0, 6.0), "s": (0.0, -6.0), "e": (6.0, 0.0),
             "w": (-6.0, 0.0)}
    for v, w in [("c", "n"), ("n", "c"), ("c", "e"), ("e", "c"), ("c", "s"), ("c", "w")]:
        start, end = (position(lanes, node) for node in lanes.ends[(v, w)])
        travel = np.subtract(nodes[w], nodes[v]) / 6.0
        right = np.array([travel[1], -travel[0]])
        # At the junction the lane is offset to the right of its travel; it ends on the dead
        # end's vertex.
        at_junction = start if v == "c" else end
        assert at_junction @ right == pytest.approx(PARAMS.offset, abs=1e-3), (v, w)


def test_plus_crossing_junction_is_a_counterclockwise_loop(plus):
    lanes, _ = plus
    corners = {name: xy for name, xy in lanes.roadways.nodes.items() if name.startswith("c")}
    assert sorted(map(tuple, corners.values())) == [
        (-0.45, -0.45), (-0.45, 0.45), (0.45, -0.45), (0.45, 0.45)]
    loop = [[a, b] for a, b in lanes.roadways.edges if a in corners and b in corners]
    assert len(loop) == 4
    for a, b in loop:
        pa, pb = np.array(corners[a]), np.array(corners[b])
        assert pa[0] * pb[1] - pa[1] * pb[0] > 0  # counterclockwise about the junction


def test_dead_ends_keep_one_node_on_the_vertex(plus):
    lanes, _ = plus
    for v in "nsew":
        assert lanes.ends[(v, "c")][0] == lanes.ends[("c", v)][1] == v
    assert lanes.roadways.nodes["n"] == [0.0, 6.0]


def test_plus_crossing_lets_robots_turn_every_way(plus):
    lanes, obstacles = plus
    graph = lane_graph(lanes.roadways)
    junction = graph.subgraph(n for n in graph if n.startswith("c"))
    for v in "nsew":
        arrive = lanes.ends[(v, "c")][1]
        for w in "nsew":
            assert nx.has_path(junction, arrive, lanes.ends[("c", w)][0]), (v, w)
    Roadways(lanes.roadways, [])  # loads as a scenario's roadways
    assert nx.is_strongly_connected(graph)
    assert min(edge_clearances(lanes.roadways, obstacles).values()) >= PARAMS.clearance


def test_l_bend_lanes_go_around_the_corner_and_keep_clearance():
    nodes = {"s": (0.0, -6.0), "k": (0.0, 0.0), "e": (6.0, 0.0)}
    lanes, obstacles = derived(L_BEND, nodes, [("s", "k"), ("k", "e")])
    assert lanes.single_file == () and lanes.tight == ()
    # Northbound then eastbound: the inner corner, one node where the lanes cross.
    assert lanes.ends[("s", "k")][1] == lanes.ends[("k", "e")][0]
    assert position(lanes, lanes.ends[("s", "k")][1]) == pytest.approx([0.45, -0.45])
    # Westbound then southbound: the outer corner, two nodes joined by a link.
    arrive, leave = lanes.ends[("e", "k")][1], lanes.ends[("k", "s")][0]
    assert position(lanes, arrive) == pytest.approx([0.0, 0.45])
    assert position(lanes, leave) == pytest.approx([-0.45, 0.0])
    assert [arrive, leave] in lanes.roadways.edges
    assert nx.is_strongly_connected(lane_graph(lanes.roadways))
    assert min(edge_clearances(lanes.roadways, obstacles).values()) >= PARAMS.clearance


def test_too_narrow_a_corridor_is_one_single_file_segment():
    nodes = {"a": (-6.0, 0.0), "b": (-2.5, 0.0), "m": (0.0, 0.0), "c": (2.5, 0.0),
             "d": (6.0, 0.0)}
    edges = [("a", "b"), ("b", "m"), ("m", "c"), ("c", "d")]
    lanes, obstacles = derived(NARROWED, nodes, edges)
    (segment,) = lanes.single_file
    assert segment.vertices in (("b", "m", "c"), ("c", "m", "b"))
    ys = [position(lanes, node)[1] for node in segment.nodes]
    assert ys == pytest.approx([0.0] * len(ys))  # on the centre-line
    xs = [position(lanes, node)[0] for node in segment.nodes]
    assert xs == sorted(xs) or xs == sorted(xs, reverse=True)
    first, last = segment.nodes[0], segment.nodes[-1]
    graph = lane_graph(lanes.roadways)
    assert nx.has_path(graph, first, last) and nx.has_path(graph, last, first)
    # Outside the narrow part: two lanes, merging into the single file.
    assert position(lanes, lanes.ends[("a", "b")][1]) == pytest.approx([-2.5, -0.45])
    assert position(lanes, lanes.ends[("b", "a")][0]) == pytest.approx([-2.5, 0.45])
    assert lanes.tight == ()
    assert min(edge_clearances(lanes.roadways, obstacles).values()) >= PARAMS.clearance
    assert nx.is_strongly_connected(graph)


def test_a_single_file_chain_ends_at_a_stop_vertex():
    # The narrow part b - m - c is one chain; with m a stop (a task location on the
    # passage), two: a robot waiting in b - m leaves m - c free for the one leaving m.
    nodes = {"a": (-6.0, 0.0), "b": (-2.5, 0.0), "m": (0.0, 0.0), "c": (2.5, 0.0),
             "d": (6.0, 0.0)}
    graph = CentrelineGraph(nodes=nodes, edges=tuple(
        CentrelineEdge(*pair) for pair in [("a", "b"), ("b", "m"), ("m", "c"), ("c", "d")]))
    field = ClearanceField.from_grid(carved(NARROWED))
    split = derive_lanes(graph, field, PARAMS, frozenset({"m"}))
    assert sorted(sorted(segment.vertices) for segment in split.single_file) == [
        ["b", "m"], ["c", "m"]]
    assert split.roadways == derive_lanes(graph, field, PARAMS).roadways  # the same lanes


def test_single_file_and_one_way_marks():
    nodes = {"c": (0.0, 0.0), "n": (0.0, 6.0), "s": (0.0, -6.0), "e": (6.0, 0.0),
             "w": (-6.0, 0.0)}
    edges = [CentrelineEdge("c", "n", single_file=True), ("s", "c"), ("c", "e"),
             CentrelineEdge("w", "c", one_way=True)]
    lanes, _ = derived(PLUS, nodes, edges)
    assert [segment.vertices for segment in lanes.single_file] == [("c", "n")]
    assert ("c", "w") not in lanes.ends  # one way only
    start, end = (position(lanes, node) for node in lanes.ends[("w", "c")])
    assert start == pytest.approx([-6.0, 0.0]) and end[1] == pytest.approx(0.0)
    assert position(lanes, lanes.ends[("c", "n")][0])[0] == pytest.approx(0.0)


def test_edge_too_short_for_its_corners_goes_single_file():
    # Two junctions 0.2 m apart on an east-west corridor: the lanes between them would run
    # backwards.
    nodes = {"j": (-0.1, 0.0), "k": (0.1, 0.0), "w": (-6.0, 0.0), "e": (6.0, 0.0),
             "n": (-0.1, 6.0), "s": (0.1, -6.0)}
    edges = [("w", "j"), ("j", "k"), ("k", "e"), ("j", "n"), ("k", "s")]
    lanes, obstacles = derived(PLUS, nodes, edges)
    # j-k goes single file (and then the edges beside it, whose corners would fall beyond
    # the other junction): every lane runs forwards.
    assert any({"j", "k"} <= set(segment.vertices) for segment in lanes.single_file)
    for (v, w), (start, end) in lanes.ends.items():
        travel = position(lanes, end) - position(lanes, start)
        assert travel @ (np.array(nodes[w]) - nodes[v]) > 0, (v, w)
    assert min(edge_clearances(lanes.roadways, obstacles).values()) >= PARAMS.clearance
    assert nx.is_strongly_connected(lane_graph(lanes.roadways))


def test_centre_line_too_close_to_a_wall_is_reported_tight():
    nodes = {"a": (-6.0, 1.0), "b": (6.0, 1.0)}  # 0.2 m from the corridor's north wall
    lanes, _ = derived(PLUS, nodes, [("a", "b")])
    assert len(lanes.single_file) == 1
    assert set(map(frozenset, lanes.tight)) == {frozenset(("a", "b"))}


@pytest.mark.parametrize("edges, field, message", [
    ([("a", "x")], "edges[0]", "unknown vertex 'x'"),
    ([("a", "b"), ("b", "a")], "edges[1]", "second edge between 'b' and 'a'"),
    ([("a", "c")], "edges[0]", "zero length: 'a' and 'c' coincide"),
])
def test_bad_centreline_graph(edges, field, message):
    with pytest.raises(InputError) as info:
        CentrelineGraph(nodes={"a": (0.0, 0.0), "b": (1.0, 0.0), "c": (0.0, 0.0)},
                        edges=tuple(CentrelineEdge(*edge) for edge in edges))
    assert str(info.value) == f"{field}: {message}"


@pytest.mark.parametrize("change, message", [
    ({"offset": 0.0}, "offset: must be > 0 m, got 0.0"),
    ({"margin": -0.1}, "margin: must be >= 0 m, got -0.1"),
    ({"robot_radius": -1.0}, "robot_radius: must be > 0 m, got -1.0"),
])
def test_bad_lane_params(change, message):
    with pytest.raises(InputError) as info:
        LaneParams(**change)
    assert str(info.value) == message
