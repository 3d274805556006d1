"""Roadways: legs on a small hand-made lane loop, travel-time estimates, validation."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig

NAVIGATION = Path(__file__).resolve().parents[2] / "models" / "hospital" / "navigation.yaml"


def loop_world():
    """A corridor along x with an eastbound lane at y = 0 and a westbound lane at y = 1.5,
    joined at both ends (right-hand traffic), and rooms A, B, C north of it at x = 5, 15, 25:
    point 3.5 m north of the lane, door above the lane, 3 queue slots on the westbound lane
    east of the door (head first), approached from the node 5 m east, left by the node 5 m
    west."""
    xs = (0, 10, 20, 30)
    nodes = {f"S{x}": [x, 0.0] for x in xs} | {f"N{x}": [x, 1.5] for x in xs}
    edges = [["S0", "S10"], ["S10", "S20"], ["S20", "S30"], ["S30", "N30"],
             ["N30", "N20"], ["N20", "N10"], ["N10", "N0"], ["N0", "S0"]]
    locations = [
        LocationConfig(
            id=i, name=name, point=[x, 5.0],
            queue=[[x + 1.0, 1.5], [x + 2.0, 1.5], [x + 3.0, 1.5]],
            entry=[[x, 2.5]], exit_node=f"N{x - 5}", approach_node=f"N{x + 5}",
        )
        for i, (name, x) in enumerate((("A", 5), ("B", 15), ("C", 25)))
    ]
    return RoadwaysConfig(nodes=nodes, edges=edges), locations


def test_legs_follow_one_way_lanes_and_end_at_the_queue_tail():
    roadways = Roadways(*loop_world())
    # A to B lies against the westbound lane: out of A, round the west end, east, back west.
    np.testing.assert_array_equal(
        roadways.leg(0, 1),
        [[5, 5], [5, 2.5], [0, 1.5], [0, 0], [10, 0], [20, 0], [30, 0], [30, 1.5],
         [20, 1.5], [18, 1.5]],
    )
    # B to A runs with it: straight down the westbound lane.
    np.testing.assert_array_equal(roadways.leg(1, 0), [[15, 5], [15, 2.5], [10, 1.5], [8, 1.5]])
    for a in roadways.location_ids:
        for b in roadways.location_ids:
            if a == b:
                continue
            leg = roadways.leg(a, b)
            np.testing.assert_array_equal(leg[-1], roadways.place(b).tail)
            nodes = [roadways.node_at(p) for p in leg]
            for u, v in zip(nodes, nodes[1:], strict=False):
                if u is not None and v is not None:
                    assert roadways.graph.has_edge(u, v), (a, b, u, v)


def test_leg_lengths_and_travel_time_estimate():
    roadways = Roadways(*loop_world())
    assert roadways.leg_length(1, 0) == pytest.approx(2.5 + math.hypot(5, 1) + 2)
    assert roadways.leg_length(2, 2) == 0.0
    times = roadways.travel_time_estimate(speed=0.5)
    assert times.dtype.kind == "i" and times.shape == (3, 3)
    assert np.all(np.diag(times) == 0)
    assert times[1, 0] == math.ceil(roadways.leg_length(1, 0) / 0.5)
    assert times[0, 1] > times[1, 0]  # one-way: A to B is the long way round
    with pytest.raises(ValueError):
        roadways.leg(1, 1)


@pytest.mark.parametrize("single_file", [[], [["N20", "N10"]]])
def test_the_estimate_counts_every_leg_as_driven(single_file):
    # One search of the lanes per exit node gives each leg's length as ``leg`` drives it
    # (off the single-file lane past the own queue where another way leads there).
    config, locations = loop_world()
    roadways = Roadways(replace(config, single_file=single_file), locations)
    ids = roadways.location_ids
    expected = [[roadways.leg_length(a, b) for b in ids] for a in ids]
    np.testing.assert_allclose(roadways.leg_lengths, expected, rtol=1e-12)
    np.testing.assert_array_equal(roadways.travel_time_estimate(0.7),
                                  np.ceil(np.array(expected) / 0.7).astype(int))
    closed = roadways.closed([(14.0, 16.0, -0.5, 0.5)])  # the eastbound lane past B
    assert closed.leg_lengths[0, 2] == math.inf  # A to C: no way east left
    assert roadways.leg_lengths[0, 2] == pytest.approx(roadways.leg_length(0, 2))


def test_route_from_a_point_joins_the_nearest_node():
    roadways = Roadways(*loop_world())
    route = roadways.route_from_point([19.0, -0.5], to_location=0)
    np.testing.assert_array_equal(route[0], [20, 0])
    np.testing.assert_array_equal(route[-1], [8, 1.5])


def _error(config, locations) -> str:
    with pytest.raises(InputError) as error:
        Roadways(config, locations, file="nav.yaml")
    return str(error.value)


def test_validation_names_file_field_and_value():
    config, locations = loop_world()
    edges = [list(edge) for edge in config.edges]
    edges[4] = ["N30", "N25"]
    message = _error(replace(config, edges=edges), locations)
    assert message.startswith("nav.yaml: roadways.edges[4]: ") and "'N25'" in message

    bad = [replace(locations[0]), replace(locations[1], exit_node="X1"), locations[2]]
    message = _error(config, bad)
    assert message.startswith("nav.yaml: locations[1].exit_node: ") and "'X1'" in message

    bad = [replace(locations[0], approach_node="Q"), *locations[1:]]
    assert "locations[0].approach_node" in _error(config, bad)

    # Without the turn at the west end nothing leaves A's exit node N0.
    no_turn = replace(config, edges=[e for e in config.edges if e != ["N0", "S0"]])
    message = _error(no_turn, locations)
    assert "approach_node" in message and "'N0'" in message and "\n" not in message

    nodes = dict(config.nodes) | {"Z": [10, 0]}
    assert "roadways.nodes.Z" in _error(replace(config, nodes=nodes), locations)
    assert "locations[2].queue" in _error(config, [*locations[:2], replace(locations[2], queue=[])])
    bad_point = [replace(locations[0], point=[1.0]), *locations[1:]]
    assert "locations[0].point" in _error(config, bad_point)


@pytest.mark.skipif(not NAVIGATION.exists(), reason="models/hospital/navigation.yaml not written")
def test_hospital_navigation_has_every_leg():
    data = yaml.safe_load(NAVIGATION.read_text())
    locations = [LocationConfig(**location) for location in data["locations"]]
    roadways = Roadways(RoadwaysConfig(**data["roadways"]), locations, file=str(NAVIGATION))
    ids = roadways.location_ids
    assert len(ids) == 6
    for a in ids:
        for b in ids:
            if a != b:
                leg = roadways.leg(a, b)
                assert len(leg) >= 2 and roadways.leg_length(a, b) > 0
                np.testing.assert_array_equal(leg[-1], roadways.place(b).tail)
        # One search for all legs out of a location: where two ways are equally short
        # (the hospital's corridors make many), possibly the other one.
        np.testing.assert_allclose(
            roadways.leg_lengths[ids.index(a)],
            [roadways.leg_length(a, b) for b in ids], rtol=1e-12)
        legs = dict(roadways.legs_from(a))
        assert sorted(legs) == [b for b in ids if b != a]
        for b, leg in legs.items():
            np.testing.assert_array_equal(leg[[0, -1]], roadways.leg(a, b)[[0, -1]])
            assert roadways.route_length(leg) == pytest.approx(roadways.leg_length(a, b),
                                                               rel=1e-12)


def test_legs_from_keep_off_the_lane_past_the_own_queue():
    config, locations = loop_world()
    roadways = Roadways(replace(config, single_file=[["N20", "N10"]]), locations)
    for a in roadways.location_ids:
        for b, leg in roadways.legs_from(a):
            np.testing.assert_array_equal(leg, roadways.leg(a, b))


def test_single_file_segments_map_their_lanes_both_ways():
    config, locations = loop_world()
    roadways = Roadways(replace(config, single_file=[["N20", "N10"]]), locations)
    assert roadways.segment_count == 1
    assert roadways.segment_of([20, 1.5], [10, 1.5]) == (0, True)  # along the node order
    assert roadways.segment_of([0, 0], [10, 0]) is None
    # A queue slot lying on the segment's lane counts as on the segment.
    assert roadways.segment_of([20, 1.5], [16.0, 1.5]) == (0, True)
    assert roadways.segment_of([30, 1.5], [22.0, 1.5]) is None


def test_bad_single_file_segment_is_one_line():
    config, locations = loop_world()
    message = _error(replace(config, single_file=[["N20", "Q"]]), locations)
    assert message.startswith("nav.yaml: roadways.single_file[0]: ") and "'Q'" in message
    assert "roadways.single_file[0]" in _error(replace(config, single_file=[["N20"]]),
                                               locations)


def test_a_robot_leaving_a_point_on_a_single_file_lane_does_not_drive_into_its_queue():
    """A 20 x 10 m ring of two-way lanes; location P on its south side, in a single-file
    segment, with its queue on the lane west of it; location W at the north-west corner."""
    nodes = {"R0": [0, 0], "P": [10, 0], "R2": [20, 0], "R3": [20, 10], "R4": [0, 10]}
    ring = ["R0", "P", "R2", "R3", "R4", "R0"]
    edges = [[a, b] for a, b in zip(ring[:-1], ring[1:], strict=True)]
    edges += [[b, a] for a, b in edges]
    locations = [
        LocationConfig(id=0, name="P", point=[10, 0], queue=[[8.7, 0]], exit_node="P",
                       approach_node="R0"),
        LocationConfig(id=1, name="W", point=[0, 10], queue=[[0, 8.7]], exit_node="R4",
                       approach_node="R0"),
    ]
    config = RoadwaysConfig(nodes=nodes, edges=edges)
    assert Roadways(config, locations).leg(0, 1)[1].tolist() == [0.0, 0.0]  # west: shortest
    single = Roadways(replace(config, single_file=[["R0", "P", "R2"]]), locations)
    leg = single.leg(0, 1)
    assert leg[1].tolist() == [20.0, 0.0]  # east, round the ring, not through its queue
    assert single.leg_length(0, 1) == pytest.approx(10 + 10 + 20 + 10 + 8.7)
    # Served beside its node (the point 0.8 m off the lane), the same.
    beside = [replace(locations[0], point=[10, -0.8]), locations[1]]
    leg = Roadways(replace(config, single_file=[["R0", "P", "R2"]]), beside).leg(0, 1)
    assert leg[:3].tolist() == [[10.0, -0.8], [10.0, 0.0], [20.0, 0.0]]
