"""Which single-file segments a robot on a route needs, and where it holds back."""

import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import (
    Need,
    SingleFileParams,
    need,
    route_runs,
    standing,
    stop_segments,
)
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig

PARAMS = SingleFileParams(request_distance=4.0, hold_distance=1.5, clear_distance=1.0,
                          chain_gap=5.0)


def roadways_nodes():
    """Nodes A0 .. A50 every 10 m along y = 0."""
    return {f"A{x}": [float(x), 0.0] for x in range(0, 60, 10)}


def roadways_edges():
    """Two-way lanes between each pair of neighbouring nodes."""
    xs = range(0, 60, 10)
    edges = [[f"A{a}", f"A{b}"] for a, b in zip(xs[:-1], xs[1:], strict=True)]
    return edges + [[b, a] for a, b in edges]


def corridor():
    """Nodes every 10 m along y = 0 (A0 .. A50): two-way lanes between each pair; the
    stretches A10-A20 and A20-A30 are two single-file segments meeting at A20, A40-A50 a
    third, 10 m of ordinary lane (A30-A40) between."""
    config = RoadwaysConfig(nodes=roadways_nodes(), edges=roadways_edges(),
                            single_file=[["A10", "A20"], ["A30", "A20"], ["A40", "A50"]])
    return Roadways(config, corridor_locations())


def corridor_locations():
    """Two locations, at each end of the corridor (A0 and A50), 3 m off its lanes."""
    return [LocationConfig(id=i, name=f"L{i}", point=[x, 3.0], queue=[[x, 1.0]],
                           exit_node=f"A{x}", approach_node=f"A{x}")
            for i, x in enumerate((0, 50))]


EAST = tuple((float(x), 0.0) for x in range(0, 60, 10))
WEST = EAST[::-1]


def test_runs_join_segments_that_meet_and_keep_the_way_driven():
    roadways = corridor()
    east = route_runs(roadways, EAST, PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in east] == [
        (1, 2, ((0, True), (1, False))), (4, 4, ((2, True),))]
    west = route_runs(roadways, WEST, PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in west] == [
        (0, 0, ((2, False),)), (2, 3, ((1, True), (0, False)))]
    # A gap shorter than chain_gap joins the runs: no waiting on 10 m of lane.
    joined = route_runs(roadways, EAST, 12.0)
    assert [(r.first, r.last) for r in joined] == [(1, 4)]


@pytest.mark.parametrize("x, index, expected", [
    (2.0, 1, Need()),  # 8 m before the stretch: nothing yet
    (7.0, 1, Need(((0, True), (1, False)), False)),  # within 4 m: ask, keep driving
    (9.0, 1, Need(((0, True), (1, False)), True)),  # within 1.5 m: hold unless granted
    (15.0, 2, Need(((0, True), (1, False)), True)),  # in it
    (30.5, 4, Need(((0, True), (1, False)), False)),  # 0.5 m past its end: keep it
    (32.0, 4, Need()),  # 2 m past: give it up
    (37.0, 4, Need(((2, True),), False, (2,))),  # the next stretch, where the route ends
])
def test_need_along_the_route(x, index, expected):
    assert need(corridor(), EAST, index, (x, 0.0), PARAMS) == expected


def test_a_hop_from_beside_the_lanes_onto_a_segment_enters_it():
    # From a queue slot beside the lanes to A20, then along segment 1 (listed A30 -> A20):
    # the robot is in segment 1 from the moment it leaves the slot.
    route = ((15.0, 2.0), (20.0, 0.0), (30.0, 0.0))
    runs = route_runs(corridor(), route, PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in runs] == [(0, 1, ((1, False),))]
    # ... and from there onto the lane's point A25 (a location's point on it).
    runs = route_runs(corridor(), ((25.0, 2.0), (25.0, 0.0)), PARAMS.chain_gap)
    assert [(r.first, r.segments) for r in runs] == [(0, ((1, True),))]
    # From A20 to a queue slot 1 m beside the lane to A30: along segment 1.
    runs = route_runs(corridor(), ((20.0, 0.0), (28.0, 1.0)), PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in runs] == [(0, 0, ((1, False),))]


@pytest.mark.parametrize("xy, spot, expected", [
    ((25.0, 0.3), (25.0, 0.0), Need(((1, True),), False, (1,), (1,))),  # in 1: asks, drives
    ((25.0, 3.0), (25.0, 0.4), Need(((1, True),), True, (1,))),  # driving up to a slot in 1
    ((25.0, 3.0), (25.0, 2.0), Need()),  # beside the lanes
    ((20.0, 0.0), (21.0, 3.0), Need(((0, False), (1, True)), False, (0, 1), (0, 1))),  # in 0, 1
])
def test_a_robot_standing_in_a_segment_or_going_to_a_spot_in_one_needs_it(xy, spot, expected):
    held = {0: False} if expected.segments[:1] == ((0, False),) else {}
    assert standing(corridor(), xy, spot, held, PARAMS) == expected


def test_segments_where_robots_stop_are_those_with_a_point_or_slot_on_their_lanes():
    roadways = corridor()
    assert stop_segments(roadways, PARAMS) == frozenset()  # points and slots 1 m off
    config = RoadwaysConfig(nodes=roadways_nodes(), edges=roadways_edges(),
                            single_file=[["A10", "A20"], ["A30", "A20"], ["A40", "A50"]])
    locations = [LocationConfig(id=0, name="on", point=[25.0, 0.0], queue=[[45.0, 0.2]],
                                exit_node="A20", approach_node="A40"),
                 LocationConfig(id=1, name="off", point=[0.0, 3.0], queue=[[0.0, 1.0]],
                                exit_node="A0", approach_node="A0")]
    assert stop_segments(Roadways(config, locations), PARAMS) == frozenset({1, 2})


def test_params_check_themselves():
    with pytest.raises(InputError, match="hold_distance"):
        SingleFileParams(hold_distance=0.0)
    with pytest.raises(InputError, match="request_distance"):
        SingleFileParams(request_distance=1.0, hold_distance=2.0)


def test_a_route_ending_where_segments_meet_asks_for_them_all_before_it_drives_in():
    # From A40 west along segment 1 to A20, where segment 0 meets it: a robot standing on
    # A20 stands in both, so it asks for both before it enters segment 1 (else it would
    # hold segment 1 and stand there in the way of a robot in segment 0 waiting for it:
    # the office's presupplies, between its corridor and supplies' room).
    route = ((40.0, 0.0), (30.0, 0.0), (20.0, 0.0))
    runs = route_runs(corridor(), route, PARAMS.chain_gap, PARAMS.stand_distance)
    assert [(r.first, r.last, r.segments) for r in runs] == [(1, 1, ((1, True), (0, True)))]
    assert need(corridor(), route, 1, (31.0, 0.0), PARAMS) == Need(((0, True), (1, True)), True,
                                                               (0, 1))  # it stops in both
    # Without the stand distance, only the segment driven.
    assert route_runs(corridor(), route, PARAMS.chain_gap)[0].segments == ((1, True),)
