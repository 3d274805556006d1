"""How long a trip between two task locations holds each room and single-file segment."""

import pytest

from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_servers import trip_holds
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from tests.navigation.test_single_file import (
    corridor,
    corridor_locations,
    roadways_edges,
    roadways_nodes,
)


def test_a_trip_holds_each_run_of_segments_from_its_request_to_its_exit():
    # L0 (beside A0) to L1 (beside A50), at 0.5 m/s: the run A10-A30 (segments 0 and 1,
    # held together) from 4 m before it (request_distance) to 1 m past it
    # (clear_distance), 25 m; the run A40-A50 (segment 2) likewise, 15 m. L1's room: 2 m
    # in from its head slot and back out, and the service.
    holds = trip_holds(corridor(), 0, 1, speed=0.5, service_time=1.0)
    assert holds == pytest.approx({(("location", 1),): 2 * 2.0 / 0.5 + 1.0,
                                   (("segment", 0), ("segment", 1)): 50.0,
                                   (("segment", 2),): 30.0})


def test_a_trip_asks_for_a_run_no_earlier_than_it_starts():
    # L1 to L0: the run A50-A40 begins 3 m from L1's point, nearer than request_distance.
    holds = trip_holds(corridor(), 1, 0, speed=0.5, service_time=1.0)
    assert holds[("segment", 2),] == pytest.approx((3.0 + 10.0 + 1.0) / 0.5)
    assert holds[("segment", 0), ("segment", 1)] == pytest.approx((4.0 + 20.0 + 1.0) / 0.5)


def test_a_robot_already_at_the_location_only_serves():
    assert trip_holds(corridor(), 1, 1, speed=0.5, service_time=1.0) == pytest.approx(
        {(("location", 1),): 9.0})


def test_serving_in_a_segment_keeps_it_busy():
    # A point 0.3 m off segment 1's lane (A20-A30): the robot serving there stands in it.
    on_lane = LocationConfig(id=2, name="L2", point=[25.0, 0.3], queue=[[25.0, 2.0]],
                             exit_node="A20", approach_node="A20")
    config = RoadwaysConfig(nodes=roadways_nodes(), edges=roadways_edges(),
                            single_file=[["A10", "A20"], ["A30", "A20"], ["A40", "A50"]])
    roadways = Roadways(config, [*corridor_locations(), on_lane])
    assert trip_holds(roadways, 2, 2, speed=0.5, service_time=1.0) == pytest.approx(
        {(("location", 2),): 2 * 1.7 / 0.5 + 1.0, (("segment", 1),): 1.0})
