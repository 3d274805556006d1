"""Navigation end to end (issue 3's done-when): six robots with fixed room sequences in the
hospital visit their rooms in order along the lanes, one robot per room at a time, and report
arrival times."""

import pathlib

import numpy as np
import pytest

from mrta_drake import load_scenario, simulate

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run():
    scenario = load_scenario(ROOT / "scenarios/hospital_routes_6_robots.yaml")
    return scenario, simulate(scenario, duration=260.0)


def test_every_robot_visits_its_rooms_in_order_and_reports_arrivals(run):
    scenario, result = run
    for robot in scenario.robots:
        arrivals = [e for e in result.events
                    if e["type"] == "arrival" and e["robot"] == robot.name]
        assert [e["location"] for e in arrivals] == robot.route, robot.name
        times = [e["at"] for e in arrivals]
        assert times == sorted(times) and times[0] > 5.0


def test_rooms_are_held_by_one_robot_at_a_time(run):
    scenario, result = run
    holders = {}
    for event in result.events:
        if event["type"] == "room":
            assert event["holder"] is None or event["holder"] not in event["waiting"]
            holders.setdefault(event["room"], []).append(event["holder"])
    assert set(holders) == {loc.id for loc in scenario.locations}
    # Physically too: never two robots standing on the same room point.
    xy = result.robot_states[..., :2]
    for location in scenario.locations:
        near = np.linalg.norm(xy - np.array(location.point), axis=-1) < 0.5
        assert near.sum(axis=1).max() <= 1, location.id


def test_robots_keep_clear_of_each_other_and_walls(run):
    _, result = run
    safety = result.summary["safety"]
    assert safety["robot_robot_contacts"] == 0 and safety["robot_wall_contacts"] == 0
    assert safety["min_robot_wall"] > 0.1
    assert result.summary["planner_failures"] == 0
