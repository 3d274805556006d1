"""Navigation derived from the hospital's real ROS map (../shared/reference/hospital_map,
never copied into the repository) and the six room points of the paper's hospital case
(models/hospital/ros_map_points.yaml): it keeps clearance, and the six-robot case runs on it
for 120 s with every robot making progress and no robot touching a wall."""

import itertools
import pathlib

import networkx as nx
import numpy as np
import pytest
import yaml

from mrta_drake import load_scenario, simulate
from mrta_drake.navigation.location_derivation import load_points
from mrta_drake.navigation.navigation_derivation import derive_navigation, write_navigation
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from mrta_drake.world.ros_map import load_ros_map
from tests.navigation.free_space_worlds import edge_clearances, lane_graph

ROOT = pathlib.Path(__file__).resolve().parents[2]
REFERENCE_MAP = ROOT.parent / "shared" / "reference" / "hospital_map" / "hospital_floor1.yaml"
POINTS = ROOT / "models" / "hospital" / "ros_map_points.yaml"


@pytest.fixture(scope="module")
def derived(tmp_path_factory):
    if not REFERENCE_MAP.is_file():
        pytest.skip("reference map not available")
    plan = load_ros_map(REFERENCE_MAP)
    navigation = derive_navigation(plan, load_points(POINTS), points_file=str(POINTS))
    path = tmp_path_factory.mktemp("ros_map") / "navigation.yaml"
    write_navigation(path, navigation, "Derived from the hospital's ROS map for a test.")
    return plan, navigation, path


def test_derived_lanes_and_queues_keep_clear_of_the_map(derived):
    plan, navigation, _ = derived
    roadways = RoadwaysConfig(**navigation["roadways"])
    locations = [LocationConfig(**item) for item in navigation["locations"]]
    assert [loc.point for loc in locations] == [p.point for p in load_points(POINTS)]
    assert min(edge_clearances(roadways, plan.obstacles).values()) >= 0.47
    for loc in locations:
        spots = np.array([*loc.queue, *loc.parking])
        assert plan.obstacles.signed_distance(spots).min() >= 0.6, loc.name
        assert 1 <= len(loc.parking) <= 2, loc.name
    Roadways(roadways, locations)
    graph = lane_graph(roadways)
    for a, b in itertools.permutations(locations, 2):
        assert nx.has_path(graph, a.exit_node, b.approach_node), (a.name, b.name)


def test_six_robot_case_runs_on_the_derived_navigation(derived, tmp_path):
    _, _, navigation_file = derived
    # The paper's six-robot case with the ROS map as its world and the derived navigation;
    # each robot gets the room sequence of the routes scenario (fixed allocator), so that
    # every robot has work from the start.
    scenario = yaml.safe_load((ROOT / "scenarios" / "hospital_6_robots.yaml").read_text())
    routes = yaml.safe_load((ROOT / "scenarios" / "hospital_routes_6_robots.yaml").read_text())
    scenario["world"] = {"kind": "ros_map", "floor_plan": str(REFERENCE_MAP)}
    scenario["locations"] = scenario["roadways"] = str(navigation_file)
    scenario["robots"] = routes["robots"]
    scenario["blocks"] = routes["blocks"]
    del scenario["tasks"]
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    result = simulate(load_scenario(path), duration=120.0)
    for robot in result.summary["robots"].values():
        assert robot["stops_completed"] >= 1
    safety = result.summary["safety"]
    assert safety["robot_wall_contacts"] == 0 and safety["min_robot_wall"] > 0.1
    assert safety["robot_robot_contacts"] == 0
    assert result.summary["planner_failures"] == 0
