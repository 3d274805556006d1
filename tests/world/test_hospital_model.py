"""Checks of the hospital model (models/hospital) against itself and the reference map."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.ndimage import distance_transform_edt

from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from mrta_drake.world.floor_plan import load_floor_plan
from mrta_drake.world.obstacles import Obstacles
from mrta_drake.world.ros_map import read_ros_map

MODEL = Path(__file__).resolve().parents[2] / "models" / "hospital"
REFERENCE_MAP = (Path(__file__).resolve().parents[3] / "shared" / "reference" / "hospital_map"
                 / "hospital_floor1.yaml")
# The six system locations of the paper's hospital case.
LOCATION_POINTS = [(0.0, 2.2), (7.9, -7.5), (7.85, -21.8), (4.25, -27.2), (-7.75, -21.7),
                   (-7.75, -7.5)]
POINT_CLEARANCE = 0.2  # m from any obstacle, for points robots stop at or pass through
LANE_CLEARANCE = 0.35  # m from any obstacle, along every lane


@pytest.fixture(scope="module")
def plan():
    return load_floor_plan(MODEL / "floor_plan.yaml")


@pytest.fixture(scope="module")
def navigation():
    content = yaml.safe_load((MODEL / "navigation.yaml").read_text())
    assert set(content) == {"locations", "roadways"}
    locations = [LocationConfig(**item) for item in content["locations"]]
    return locations, RoadwaysConfig(**content["roadways"])


@pytest.fixture(scope="module")
def reference():
    if not REFERENCE_MAP.is_file():
        pytest.skip("reference map not available")
    return read_ros_map(REFERENCE_MAP)


def polyline(points, step=0.1) -> np.ndarray:
    """Points every ``step`` m (or closer) along a polyline, ends included."""
    points = np.asarray(points, dtype=float)
    parts = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
        parts.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.concatenate(parts)


def location_paths(location: LocationConfig, nodes) -> dict[str, np.ndarray]:
    """The way in (approach node, queue from tail to head, entry, point) and out (point,
    entry reversed, exit node), sampled every 0.1 m."""
    way_in = [nodes[location.approach_node], *location.queue[::-1], *location.entry,
              location.point]
    way_out = [location.point, *location.entry[::-1], nodes[location.exit_node]]
    return {"in": polyline(way_in), "out": polyline(way_out)}


def lanes(roadways: RoadwaysConfig) -> dict[tuple[str, str], np.ndarray]:
    return {(a, b): polyline([roadways.nodes[a], roadways.nodes[b]]) for a, b in roadways.edges}


def test_plan_matches_reference_frame(plan):
    assert plan.name == "hospital_floor1"
    assert plan.bounds == (-12.5, 12.5, -35.0, 20.95)
    assert plan.occupancy(0.05).shape == (1119, 500)


def test_locations(plan, navigation):
    locations, roadways = navigation
    assert [loc.id for loc in locations] == list(range(6))
    for loc, expected in zip(locations, LOCATION_POINTS, strict=True):
        assert tuple(loc.point) == expected
        assert plan.places[loc.name] == expected
        assert loc.exit_node in roadways.nodes and loc.approach_node in roadways.nodes
        queue = np.array(loc.queue)
        assert queue.shape == (3, 2)
        np.testing.assert_allclose(np.linalg.norm(np.diff(queue, axis=0), axis=1), 1.0)
        # The head slot is the one nearest the door (the first entry point, or the point).
        door = np.array(loc.entry[0] if loc.entry else loc.point)
        assert np.argmin(np.linalg.norm(queue - door, axis=1)) == 0


def test_location_points_are_clear(plan, navigation):
    locations, _ = navigation
    grid = plan.occupancy(0.05)
    for loc in locations:
        points = np.array([loc.point, *loc.queue, *loc.entry, *loc.parking])
        assert grid.is_free(points).all(), loc.name
        assert plan.obstacles.signed_distance(points).min() >= POINT_CLEARANCE, loc.name
        # Parking leaves the point free for the next robot, and room for two robots.
        spots = np.array(loc.parking)
        assert len(spots) == 2, loc.name
        assert (np.linalg.norm(spots - loc.point, axis=1) > 1.5).all(), loc.name
        assert np.linalg.norm(spots[0] - spots[1]) > 1.0, loc.name
        assert plan.obstacles.signed_distance(points).min() >= POINT_CLEARANCE, loc.name


def test_robots_can_reach_the_points_they_stop_at(plan, navigation):
    # The controller keeps robot centres its wall safety distance from walls: a point nearer
    # a wall is out of reach (queue slots once were, by up to 0.18 m: a robot waiting at
    # one kept turning to the wall and pushing into its barrier).
    from mrta_drake.control.barriers import SafetyDistances

    locations, _ = navigation
    reach = SafetyDistances().wall
    for loc in locations:
        points = np.array([loc.point, *loc.queue, *loc.entry, *loc.parking])
        clearance = plan.obstacles.signed_distance(points)
        assert clearance.min() >= reach, (loc.name, points[clearance.argmin()])


def test_location_paths_are_clear(plan, navigation):
    locations, roadways = navigation
    for loc in locations:
        for way, points in location_paths(loc, roadways.nodes).items():
            clearance = plan.obstacles.signed_distance(points)
            assert clearance.min() >= POINT_CLEARANCE, (loc.name, way, points[clearance.argmin()])


def test_lanes_are_clear(plan, navigation):
    _, roadways = navigation
    grid = plan.occupancy(0.05)
    for edge, points in lanes(roadways).items():
        assert grid.is_free(points).all(), edge
        clearance = plan.obstacles.signed_distance(points)
        assert clearance.min() >= LANE_CLEARANCE, (edge, points[clearance.argmin()])


def test_everything_robots_use_is_free_in_the_reference(reference, navigation):
    locations, roadways = navigation
    for loc in locations:
        for way, points in location_paths(loc, roadways.nodes).items():
            free = reference.is_free(points)
            assert free.all(), (loc.name, way, points[~free][:3])
    for edge, points in lanes(roadways).items():
        free = reference.is_free(points)
        assert free.all(), (edge, points[~free][:3])


def test_roadways_connect_all_locations(navigation):
    locations, roadways = navigation
    successors = {name: [] for name in roadways.nodes}
    for edge in roadways.edges:
        assert len(edge) == 2 and all(node in roadways.nodes for node in edge), edge
        successors[edge[0]].append(edge[1])

    def reachable(start):
        seen, stack = {start}, [start]
        while stack:
            for nxt in successors[stack.pop()]:
                if nxt not in seen:
                    seen.add(nxt)
                    stack.append(nxt)
        return seen

    for source in locations:
        reached = reachable(source.exit_node)
        for target in locations:
            assert target.approach_node in reached, (source.name, target.name)


def test_walls_coincide_with_the_reference(plan, reference):
    raw = yaml.safe_load((MODEL / "floor_plan.yaml").read_text())
    wall_names = {wall["name"] for wall in raw["walls"]}
    walls = Obstacles(tuple(box for box in plan.obstacles.boxes
                            if box.name in wall_names or box.name.rsplit("_", 1)[0] in wall_names))
    assert len(walls.boxes) >= len(wall_names)
    ours = walls.rasterize(plan.bounds, reference.resolution).occupied
    assert ours.shape == reference.occupied.shape
    distance = distance_transform_edt(~reference.occupied) * reference.resolution
    assert np.mean(distance[ours] <= 0.3) >= 0.8
