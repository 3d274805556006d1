"""Tests of locations from named points (mrta_drake/navigation/location_derivation.py): the
points file, accesses and bad input."""

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.clearance_field import ClearanceField
from mrta_drake.navigation.lane_derivation import CentrelineEdge, CentrelineGraph, LaneParams
from mrta_drake.navigation.location_derivation import (
    LocationParams,
    NamedPoint,
    attach_points,
    load_points,
    with_access_stubs,
)
from mrta_drake.navigation.navigation_derivation import derive_navigation
from tests.navigation.free_space_worlds import PLUS, carved

LANES = LaneParams()
CORRIDOR = CentrelineGraph(nodes={"w": (-6.0, 0.0), "e": (6.0, 0.0)},
                           edges=(CentrelineEdge("w", "e"),))
# An east-west corridor 2.4 m wide with a 4 m x 4 m room north of it (doorway x -0.7..0.7),
# and a closed 2 m x 2 m cupboard south of it.
ROOM = [(-8.0, 8.0, -1.2, 1.2), (-2.0, 2.0, 2.4, 6.5), (-0.7, 0.7, 1.0, 2.6),
        (-1.0, 1.0, -4.0, -2.0)]


@pytest.fixture(scope="module")
def field():
    return ClearanceField.from_grid(carved(ROOM))


def test_points_file(tmp_path):
    path = tmp_path / "points.yaml"
    path.write_text("points:\n  - {name: lobby, point: [0.0, 2.2], parking: true}\n"
                    "  - {name: room_1, point: [7.9, -7.5]}\n")
    assert load_points(path) == [NamedPoint("lobby", [0.0, 2.2], True),
                                 NamedPoint("room_1", [7.9, -7.5], False)]


@pytest.mark.parametrize("text, field, message", [
    ("points: []", "points", "at least two points are required (the roadways join them), "
     "got 0"),
    ("points: [{name: a, point: [1.0, 1.0]}]", "points", "at least two points are required "
     "(the roadways join them), got 1"),
    ("points:\n  - {point: [0, 0]}", "points[0].name", "is required"),
    ("points:\n  - {name: a, point: [0, 0]}\n  - {name: a, point: [1, 0]}", "points[1].name",
     "duplicate name 'a'"),
    ("points:\n  - {name: a, point: [0]}", "points[0].point",
     "expected [x, y] in metres, got [0.0]"),
    ("points:\n  - {name: a, point: [0, 0], colour: red}", "points[0].colour",
     "unknown field"),
    ("points:\n  - {name: a, point: [0, 0]}\n  - {name: b, point: [3, 0]}\n"
     "  - {name: c, point: [0.3, 0.4]}", "points[2].point",
     "[0.3, 0.4] is 0.50 m from points[0] ('a'); points must be at least 1 m apart"),
])
def test_bad_points_file(tmp_path, text, field, message):
    path = tmp_path / "points.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_points(path)
    assert str(info.value).startswith(f"{path}: {field}: {message}")


def test_access_from_the_nearest_centre_line_point_in_sight(field):
    graph = attach_points(CORRIDOR, [NamedPoint("p", [2.0, 0.7])], field, LANES)
    assert graph.nodes["p_access"] == pytest.approx((2.0, 0.0))
    assert CentrelineEdge("p_access", "p", single_file=True) in graph.edges
    # Near a vertex: joins it.
    graph = attach_points(CORRIDOR, [NamedPoint("q", [5.8, 0.6])], field, LANES)
    assert CentrelineEdge("e", "q", single_file=True) in graph.edges


def test_point_on_a_centre_line_becomes_a_dead_end_with_a_stub(field):
    graph = attach_points(CORRIDOR, [NamedPoint("p", [5.0, 0.05])], field, LANES)
    assert graph.nodes["p"] == (5.0, 0.05) and "p_access" not in graph.nodes
    pruned = CentrelineGraph(nodes={v: xy for v, xy in graph.nodes.items() if v != "e"},
                             edges=tuple(e for e in graph.edges if "e" not in (e.a, e.b)))
    stubbed = with_access_stubs(pruned, [NamedPoint("p", [5.0, 0.05])])
    assert np.linalg.norm(np.subtract(stubbed.nodes["p_access"], (5.0, 0.05))) == \
        pytest.approx(1.0)
    assert CentrelineEdge("p_access", "p", single_file=True) in stubbed.edges
    with pytest.raises(InputError) as info:
        with_access_stubs(graph, [NamedPoint("p", [5.0, 0.05])], file="points.yaml")
    assert str(info.value) == ("points.yaml: points[0].point: [5.0, 0.05] lies on a passage "
                               "between other places; move it aside (at least 0.1 m) so that "
                               "it gets a dead-end access")


@pytest.mark.parametrize("point, message", [
    ([3.0, 1.0], "[3.0, 1.0] is 0.13 m from an obstacle; a location needs 0.47 m"),
    ([0.0, -3.0], "[0.0, -3.0]: no centre-line in sight keeping 0.47 m from obstacles"),
])
def test_bad_points(field, point, message):
    with pytest.raises(InputError) as info:
        attach_points(CORRIDOR, [NamedPoint("p", point)], field, LANES, file="points.yaml")
    assert str(info.value) == f"points.yaml: points[0].point: {message}"


def test_parking_that_does_not_fit():
    points = [NamedPoint("n", [0.0, 6.2], parking=True), NamedPoint("s", [0.0, -6.2])]
    with pytest.raises(InputError) as info:
        derive_navigation(carved(PLUS), points, points_file="points.yaml")
    assert str(info.value) == "points.yaml: points[0].parking: no parking spot fits around " \
                              "[0.0, 6.2]"


@pytest.mark.parametrize("change, message", [
    ({"queue_slots": 0}, "queue_slots: must be >= 1, got 0"),
    ({"slot_spacing": 0.0}, "slot_spacing: must be > 0 m, got 0.0"),
    ({"snap": -0.1}, "snap: must be >= 0 m, got -0.1"),
    ({"parking_distance": (2.0, 1.0)}, "parking_distance: need 0 < min <= max, got [2.0, 1.0]"),
])
def test_bad_location_params(change, message):
    with pytest.raises(InputError) as info:
        LocationParams(**change)
    assert str(info.value) == message
