"""Objects placed by Scenic programs: seeded scenes, clear of walls, each other, robot starts
and lanes; in the one obstacle source, so they block the planner and reach the plant."""

import dataclasses
import pathlib
import random
import sys

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.world.plant import load_floor_plan_of, resolve_locations

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"
CARTS = ROOT / "scenarios/scenic/hospital_carts.scenic"
BLOCKED = ROOT / "scenarios/scenic/hospital_blocked_corridor.scenic"


@pytest.fixture(scope="module")
def routes():
    return load_scenario(ROUTES)


def with_program(scenario, program, seed=0, **params):
    world = dataclasses.replace(scenario.world, scenic=str(program), scenic_params=params)
    return dataclasses.replace(scenario, world=world, seed=seed)


def added(scenario):
    """The obstacles the scenario's Scenic program adds: (boxes, cylinders)."""
    base = load_floor_plan_of(scenario, objects=False).obstacles
    full = load_floor_plan_of(scenario).obstacles
    return full.boxes[len(base.boxes):], full.cylinders[len(base.cylinders):]


def test_without_scenic_sampling_says_how_to_install_it(routes, monkeypatch):
    monkeypatch.setitem(sys.modules, "scenic", None)  # import scenic now fails
    with pytest.raises(InputError, match=r"pip install 'mrta-drake\[scenic\]'") as error:
        load_floor_plan_of(with_program(routes, CARTS))
    assert error.value.field == "world.scenic"


def test_a_seed_gives_one_scene_and_leaves_global_random_state_alone(routes):
    pytest.importorskip("scenic")
    random.seed(123)
    np.random.seed(123)
    first = added(with_program(routes, CARTS, seed=3))
    after = (random.random(), np.random.random())
    random.seed(123)
    np.random.seed(123)
    assert after == (random.random(), np.random.random())
    assert added(with_program(routes, CARTS, seed=3)) == first
    assert added(with_program(routes, CARTS, seed=4)) != first
    boxes, cylinders = first
    names = sorted(o.name.rsplit("_", 1)[0] for o in boxes + cylinders)
    assert names == ["bed", "bin", "bin", "bookshelf", "bookshelf", "cart", "cart", "cart"]
    counts = added(with_program(routes, CARTS, seed=3, carts=1, shelves=0, bins=0, beds=0))
    assert [o.name for o in counts[0] + counts[1]] == ["cart_0"]


@pytest.mark.parametrize("seed", range(4))
def test_objects_stay_clear_of_walls_each_other_robot_starts_and_lanes(routes, seed):
    pytest.importorskip("scenic")
    from shapely.geometry import Point

    from mrta_drake.world.scenic_objects import LANE_CLEARANCE, footprint, lane_area, traffic_lines

    scenario = with_program(routes, CARTS, seed=seed)
    floor_plan = load_floor_plan_of(scenario, objects=False)
    boxes, cylinders = added(scenario)
    shapes = [footprint(o) for o in boxes + cylinders]
    obstacles = floor_plan.obstacles
    walls = [footprint(o) for o in obstacles.boxes + obstacles.cylinders]
    starts = [Point(r.start[:2]).buffer(r.radius) for r in routes.robots]
    lanes = lane_area(traffic_lines(resolve_locations(routes, floor_plan)),
                      LANE_CLEARANCE + max(r.radius for r in routes.robots))
    tolerance = 1e-6  # m^2 of overlap area
    for k, shape in enumerate(shapes):
        assert shape.intersection(lanes).area < tolerance
        for other in walls + starts + shapes[:k]:
            assert shape.intersection(other).area < tolerance


def test_objects_across_a_corridor_make_the_planner_detour(routes):
    pytest.importorskip("scenic")
    from mrta_drake.navigation.costmap import Costmap
    from mrta_drake.navigation.grid_planner import GridPlanner, PlannerParams

    start, goal = (4.9, -16.6), (4.9, -21.0)  # the east corridor, either side of the bed

    def plan(floor_plan):
        costmap = Costmap.from_obstacles(floor_plan.obstacles, floor_plan.bounds,
                                         resolution=0.1)
        return GridPlanner(costmap, PlannerParams(landmarks=0)).plan(start, goal)

    scenario = with_program(routes, BLOCKED, seed=5)
    clear = plan(load_floor_plan_of(scenario, objects=False))
    blocked = plan(load_floor_plan_of(scenario))
    assert clear.found and blocked.found

    def length(result):
        return float(np.linalg.norm(np.diff(result.points, axis=0), axis=1).sum())

    assert length(clear) == pytest.approx(4.4, abs=0.3)
    assert length(blocked) > 5 * length(clear)
    assert blocked.points[:, 0].min() < -3.0  # round by the west corridor


def test_scenario_objects_reach_the_plant(routes):
    pytest.importorskip("scenic")
    from mrta_drake.stack.diagram import build_diagram

    scenario = load_scenario(ROOT / "scenarios/hospital_carts.yaml")
    stack = build_diagram(scenario)
    obstacles = stack.world.obstacles
    assert any(b.name.startswith("cart_") for b in obstacles.boxes)
    assert any(c.name.startswith("bin_") for c in obstacles.cylinders)
    plant = stack.world.plant
    geometries = plant.GetCollisionGeometriesForBody(plant.world_body())
    assert len(geometries) == len(obstacles)
    inspector = stack.world.scene_graph.model_inspector()
    names = {inspector.GetName(g) for g in geometries}
    assert any("::cart_" in name or name.startswith("cart_") for name in names)


def test_program_errors_name_the_program(routes, tmp_path):
    pytest.importorskip("scenic")
    broken = tmp_path / "broken.scenic"
    broken.write_text("model mrta_drake.world.scenic_model\nnew Cart at (0, 0\n")
    with pytest.raises(InputError) as error:
        load_floor_plan_of(with_program(routes, broken))
    assert error.value.file == str(broken)
    impossible = tmp_path / "impossible.scenic"
    # Always on robot1's start (0, 2.2): every scene is rejected.
    impossible.write_text("model mrta_drake.world.scenic_model\n"
                          "new Bin at (Range(-0.1, 0.1), Range(2.1, 2.3))\n")
    with pytest.raises(InputError, match="no scene met the program's requirements"):
        load_floor_plan_of(with_program(routes, impossible))
    with pytest.raises(InputError) as error:
        load_floor_plan_of(with_program(routes, CARTS, free_space=None))
    assert error.value.field == "world.scenic_params.free_space"


def test_missing_program_file_is_a_scenario_error(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(ROUTES.read_text().replace("../models", str(ROOT / "models"))
                    .replace("floor_plan.yaml", "floor_plan.yaml\n  scenic: nowhere.scenic", 1))
    with pytest.raises(InputError, match="file not found: 'nowhere.scenic'") as error:
        load_scenario(path)
    assert error.value.field == "world.scenic"
