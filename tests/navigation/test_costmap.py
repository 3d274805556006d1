"""Costmap: Nav2 inflation-layer costs over an occupancy grid."""

import math

import numpy as np
import pytest

from mrta_drake.navigation.costmap import (
    DEFAULT_RESOLUTION,
    FREE,
    INSCRIBED,
    LETHAL,
    MAX_CELLS,
    MAX_NON_OBSTACLE,
    Costmap,
    CostmapParams,
    inflation_cost,
    resolution_for,
)
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid


def nav2_cost(distance_m, params: CostmapParams, resolution: float) -> int:
    """Nav2's InflationLayer::computeCost, written out for one cell."""
    if distance_m == 0.0:
        return 254
    if distance_m > math.ceil(params.inflation_radius / resolution) * resolution + 1e-12:
        return 0
    if distance_m <= params.robot_radius:
        return 253
    return int(252 * math.exp(-params.cost_scaling * (distance_m - params.robot_radius)))


def single_obstacle(size=31, resolution=0.05) -> OccupancyGrid:
    occupied = np.zeros((size, size), dtype=bool)
    occupied[size // 2, size // 2] = True
    return OccupancyGrid(occupied, resolution, (0.0, 0.0))


def test_costs_around_one_obstacle_cell_follow_the_nav2_formula():
    grid = single_obstacle()
    costmap = Costmap.from_grid(grid)
    params = CostmapParams()
    assert (params.robot_radius, params.inflation_radius, params.cost_scaling) == (0.22, 0.5, 3.0)
    c = 15
    for i in range(31):
        for j in range(31):
            d = math.hypot(i - c, j - c) * 0.05
            assert costmap.cost[i, j] == nav2_cost(d, params, 0.05), (i, j)
    # Spot values: 0.25 m -> floor(252 e^-0.09) = 230; 0.5 m -> floor(252 e^-0.84) = 108.
    assert costmap.cost[c, c] == LETHAL
    assert costmap.cost[c, c + 4] == INSCRIBED
    assert costmap.cost[c, c + 5] == 230
    assert costmap.cost[c, c + 10] == 108
    assert costmap.cost[c, c + 11] == FREE


def test_inflation_cost_is_vectorized_and_monotone():
    d = np.linspace(0.0, 1.0, 201)
    cost = inflation_cost(d, 0.22, 0.5, 3.0, 0.05)
    assert cost.dtype == np.uint8
    assert np.all(np.diff(cost.astype(int)) <= 0)
    assert [int(c) for c in inflation_cost([0.0, 0.1, 0.3], 0.22, 0.5, 3.0, 0.05)] == [
        254, 253, int(252 * math.exp(-3.0 * 0.08))]


@pytest.mark.parametrize("seed", range(5))
def test_random_grids_match_a_brute_force_distance(seed):
    rng = np.random.default_rng(seed)
    occupied = rng.random((24, 30)) < 0.03
    occupied[rng.integers(24), rng.integers(30)] = True
    params = CostmapParams(robot_radius=0.15, inflation_radius=0.4, cost_scaling=5.0)
    costmap = Costmap.from_grid(OccupancyGrid(occupied, 0.05, (-1.0, 2.0)), params)
    obstacle = np.argwhere(occupied)
    cells = np.argwhere(np.ones_like(occupied))
    distance = np.min(np.linalg.norm(cells[:, None, :] - obstacle[None], axis=-1), axis=1)
    expected = [nav2_cost(d * 0.05, params, 0.05) for d in distance]
    np.testing.assert_array_equal(costmap.cost.ravel(), expected)


def test_from_obstacles_marks_boxes_lethal_and_queries_world_points():
    box = Box("crate", center=(1.0, 1.0), size=(0.4, 0.4))
    costmap = Costmap.from_obstacles(Obstacles(boxes=(box,)), (0.0, 2.0, 0.0, 2.0))
    assert costmap.shape == (40, 40) and costmap.resolution == 0.05
    assert costmap.cost_at((1.0, 1.0)) == LETHAL
    assert costmap.cost_at((1.0, 1.3)) == INSCRIBED  # 0.1 m from the box
    assert costmap.cost_at((1.9, 1.9)) == FREE
    assert costmap.cost_at((5.0, 1.0)) == LETHAL  # off the grid
    np.testing.assert_array_equal(costmap.is_traversable([(1.0, 1.3), (1.9, 1.9)]),
                                  [False, True])
    assert not costmap.cost.flags.writeable


def test_added_obstacles_cost_the_same_with_their_footprints_remembered():
    """``with_obstacles`` remembers each obstacle's footprint; a soft one shares the grid."""
    walls = Obstacles(boxes=(Box("wall", (1.0, 0.5), (2.0, 0.1)),))
    bounds = (0.0, 2.0, 0.0, 2.0)
    added = Obstacles(boxes=(Box("crate", (0.5, 1.4), (0.3, 0.3)),),
                      cylinders=(Cylinder("robot", (1.4, 1.2), 0.4),
                                 Cylinder("away", (9.0, 9.0), 0.4)))  # off the grid
    base = Costmap.from_obstacles(walls, bounds)
    soft = base.with_obstacles(added, MAX_NON_OBSTACLE)
    hard = base.with_obstacles(added)  # from the footprints the soft one left

    def fresh(cost=LETHAL):
        return Costmap.from_obstacles(walls, bounds).with_obstacles(added, cost)

    for remembered, expected in ((soft, fresh(MAX_NON_OBSTACLE)), (hard, fresh())):
        np.testing.assert_array_equal(remembered.cost, expected.cost)
        np.testing.assert_array_equal(remembered.grid.occupied, expected.grid.occupied)
    assert soft.grid is base.grid and soft.distance is base.distance
    assert np.any(soft.cost != base.cost) and np.any(hard.grid.occupied != base.grid.occupied)


def test_an_empty_grid_is_free_everywhere():
    costmap = Costmap.from_grid(OccupancyGrid(np.zeros((5, 6), bool), 0.05, (0.0, 0.0)))
    assert np.all(costmap.cost == FREE) and np.all(np.isinf(costmap.distance))


def test_bad_params_are_refused():
    with pytest.raises(ValueError):
        CostmapParams(robot_radius=0.6, inflation_radius=0.5)
    with pytest.raises(ValueError):
        CostmapParams(cost_scaling=-1.0)


def test_resolution_coarsens_only_for_very_large_worlds():
    assert resolution_for((-20.0, 20.0, -35.0, 5.0)) == DEFAULT_RESOLUTION  # a hospital floor
    assert resolution_for((0.0, 100.0, 0.0, 100.0)) == DEFAULT_RESOLUTION  # just fits
    campus = (0.0, 321.0, 0.0, 248.0)
    resolution = resolution_for(campus)
    assert resolution == 0.15
    assert 321.0 * 248.0 / resolution**2 <= MAX_CELLS < 321.0 * 248.0 / 0.1**2
