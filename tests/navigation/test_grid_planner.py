"""GridPlanner: optimal against a brute-force Dijkstra, clear of obstacles, never raising."""

import math

import networkx as nx
import numpy as np
import pytest

from mrta_drake.navigation.costmap import INSCRIBED, MAX_NON_OBSTACLE, Costmap, CostmapParams
from mrta_drake.navigation.grid_planner import (
    GOAL_IN_OBSTACLE,
    GOAL_OFF_GRID,
    START_IN_OBSTACLE,
    START_OFF_GRID,
    UNREACHABLE,
    GridPlanner,
    PlannerParams,
)
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid

RESOLUTION = 0.1
SMALL_ROBOT = CostmapParams(robot_radius=0.15, inflation_radius=0.5, cost_scaling=3.0)


def random_costmap(seed: int, shape=(30, 40)) -> Costmap:
    """Random axis-aligned blocks on a grid of 0.1 m cells."""
    rng = np.random.default_rng(seed)
    occupied = np.zeros(shape, dtype=bool)
    for _ in range(rng.integers(3, 9)):
        i, j = rng.integers(0, shape[0]), rng.integers(0, shape[1])
        occupied[i:i + rng.integers(1, 8), j:j + rng.integers(1, 10)] = True
    return Costmap.from_grid(OccupancyGrid(occupied, RESOLUTION, (-1.5, 0.5)), SMALL_ROBOT)


def dijkstra_graph(costmap: Costmap, cost_weight: float) -> nx.Graph:
    """The planner's cost model as an explicit graph: a move between 8-neighbours u, v costs
    |uv| * (factor(u) + factor(v)) / 2 with factor = 1 + w * cost / 252, in metres; a
    diagonal move needs both cells beside it free."""
    factor = 1.0 + cost_weight * costmap.cost / MAX_NON_OBSTACLE
    free = costmap.cost < INSCRIBED
    rows, cols = costmap.shape
    graph = nx.Graph()
    for i, j in zip(*np.nonzero(free), strict=True):
        graph.add_node((i, j))
        for di, dj in ((0, 1), (1, -1), (1, 0), (1, 1)):
            ni, nj = i + di, j + dj
            if not (0 <= ni < rows and 0 <= nj < cols) or not free[ni, nj]:
                continue
            if di and dj and not (free[i, nj] and free[ni, j]):
                continue
            step = math.hypot(di, dj) * costmap.resolution
            graph.add_edge((i, j), (ni, nj), weight=step * 0.5 * (factor[i, j] + factor[ni, nj]))
    return graph


def centre(costmap: Costmap, cell) -> np.ndarray:
    return costmap.grid.cell_to_world(*cell)


def assert_clear(costmap: Costmap, points: np.ndarray, step: float = 0.005):
    """Every point densely sampled along the polyline is on a traversable cell."""
    for a, b in zip(points[:-1], points[1:], strict=True):
        count = max(int(np.linalg.norm(b - a) / step), 1)
        samples = a + np.linspace(0.0, 1.0, count + 1)[:, None] * (b - a)
        assert np.all(costmap.is_traversable(samples)), (a, b)


@pytest.mark.parametrize("landmarks", [0, 4])
@pytest.mark.parametrize("seed", range(6))
def test_optimal_cost_equals_brute_force_dijkstra(seed, landmarks):
    costmap = random_costmap(seed)
    params = PlannerParams(cost_weight=2.0, landmarks=landmarks)
    planner = GridPlanner(costmap, params)
    graph = dijkstra_graph(costmap, params.cost_weight)
    rng = np.random.default_rng(100 + seed)
    nodes = list(graph.nodes)
    for _ in range(8):
        a = nodes[rng.integers(len(nodes))]
        b = nodes[rng.integers(len(nodes))]
        result = planner.plan(centre(costmap, a), centre(costmap, b))
        if nx.has_path(graph, a, b):
            expected = nx.dijkstra_path_length(graph, a, b)
            assert result.found
            assert result.cost == pytest.approx(expected, rel=1e-6)
            # The returned cells are a connected path whose own cost is that optimum.
            cells = [tuple(c) for c in result.cells]
            assert cells[0] == a and cells[-1] == b
            steps = zip(cells[:-1], cells[1:], strict=True)
            own_cost = sum(graph.edges[u, v]["weight"] for u, v in steps)
            assert own_cost == pytest.approx(expected, rel=1e-9)
        else:
            assert result.failure == UNREACHABLE


@pytest.mark.parametrize("seed", range(6))
def test_paths_stay_out_of_the_lethal_and_inscribed_zone(seed):
    costmap = random_costmap(seed)
    planner = GridPlanner(costmap, PlannerParams(point_spacing=0.2))
    free = np.argwhere(costmap.cost < INSCRIBED)
    rng = np.random.default_rng(seed)
    found = 0
    for _ in range(10):
        start = centre(costmap, free[rng.integers(len(free))]) + rng.uniform(-0.04, 0.04, 2)
        goal = centre(costmap, free[rng.integers(len(free))]) + rng.uniform(-0.04, 0.04, 2)
        result = planner.plan(start, goal)
        if not result.found:
            continue
        found += 1
        assert np.all(costmap.cost[result.cells[:, 0], result.cells[:, 1]] < INSCRIBED)
        np.testing.assert_allclose(result.points[0], start)
        np.testing.assert_allclose(result.points[-1], goal)
        gaps = np.linalg.norm(np.diff(result.points, axis=0), axis=1)
        assert np.all(gaps <= 0.2 + 1e-9)
        assert_clear(costmap, result.points)
        # Shortcutting never makes the path longer than the grid path it replaces.
        cell_path = centre(costmap, result.cells.T)
        raw = np.sum(np.linalg.norm(np.diff(cell_path, axis=0), axis=1))
        assert np.sum(gaps) <= raw + 2 * costmap.resolution
    assert found >= 3


def room_with_closet() -> Costmap:
    """A 6 m x 4 m walled room, a 1 m x 1 m walled closet inside it with no door."""
    walls = [Box("south", (3.0, 0.05), (6.0, 0.1)), Box("north", (3.0, 3.95), (6.0, 0.1)),
             Box("west", (0.05, 2.0), (0.1, 4.0)), Box("east", (5.95, 2.0), (0.1, 4.0)),
             Box("closet", (4.5, 2.0), (1.2, 1.2)), Box("pillar", (2.0, 2.0), (0.4, 0.4))]
    closet_inside = Box("hollow", (4.5, 2.0), (1.0, 1.0))
    grid = Obstacles(boxes=tuple(walls)).rasterize((0.0, 6.0, 0.0, 4.0), 0.05)
    hollow = Obstacles(boxes=(closet_inside,)).rasterize((0.0, 6.0, 0.0, 4.0), 0.05)
    return Costmap.from_grid(OccupancyGrid(grid.occupied & ~hollow.occupied, 0.05, (0.0, 0.0)))


@pytest.fixture(scope="module")
def room_planner() -> GridPlanner:
    return GridPlanner(room_with_closet())


def test_failures_are_reported_never_raised(room_planner):
    open_floor = (1.0, 1.0)
    cases = {
        UNREACHABLE: (open_floor, (4.5, 2.0)),  # inside the closed closet
        GOAL_IN_OBSTACLE: (open_floor, (2.0, 2.0)),  # inside the pillar
        START_IN_OBSTACLE: ((2.0, 2.0), open_floor),
        GOAL_OFF_GRID: (open_floor, (9.0, 1.0)),
        START_OFF_GRID: ((np.nan, 1.0), open_floor),
    }
    for reason, (start, goal) in cases.items():
        result = room_planner.plan(start, goal)
        assert not result.found and result.failure == reason
        assert result.points.shape == (0, 2) and result.cost == math.inf


def test_a_goal_beside_a_wall_snaps_out_of_the_inscribed_zone(room_planner):
    costmap = room_planner.costmap
    start, goal = np.array([3.0, 1.0]), np.array([1.0, 0.25])  # 0.15 m from the south wall
    assert costmap.cost_at(goal) == INSCRIBED
    result = room_planner.plan(start, goal)
    assert result.found
    np.testing.assert_allclose(result.points[0], start)
    assert np.linalg.norm(result.points[-1] - goal) <= room_planner.params.snap_radius
    assert_clear(costmap, result.points)
    # And back again: only the first leg, out of the inscribed zone, may cross it.
    back = room_planner.plan(goal, start)
    assert back.found
    np.testing.assert_allclose(back.points[0], goal)
    assert_clear(costmap, back.points[1:])


def test_paths_go_around_the_pillar_and_are_symmetric(room_planner):
    there = room_planner.plan((0.8, 2.0), (3.2, 2.0))
    back = room_planner.plan((3.2, 2.0), (0.8, 2.0))
    assert there.found and back.found
    assert there.cost == pytest.approx(back.cost, rel=1e-6)
    assert there.cost > 2.4  # longer than the straight line through the pillar
    assert_clear(room_planner.costmap, there.points)
    assert not there.points.flags.writeable


def test_same_cell_start_and_goal():
    planner = GridPlanner(random_costmap(0))
    free = np.argwhere(planner.costmap.cost == 0)[0]
    point = centre(planner.costmap, free)
    result = planner.plan(point, point + 0.01)
    assert result.found and result.cost == 0.0 and len(result.points) >= 2


def test_bad_params_are_refused():
    with pytest.raises(ValueError):
        PlannerParams(point_spacing=0.0)
    with pytest.raises(ValueError):
        PlannerParams(landmarks=-1)


def test_a_full_search_heap_grows_and_gives_the_same_path():
    costmap, params = random_costmap(3), PlannerParams(landmarks=0)
    free = np.argwhere(costmap.cost == 0)
    start, goal = centre(costmap, free[0]), centre(costmap, free[-1])
    expected = GridPlanner(costmap, params).plan(start, goal)
    assert expected.found
    planner = GridPlanner(costmap, params)
    planner._heap_key, planner._heap_item = np.empty(2), np.empty(2, dtype=np.int64)
    again = planner.plan(start, goal)
    assert len(planner._heap_key) > 2
    assert again.cost == expected.cost
    np.testing.assert_array_equal(again.cells, expected.cells)


@pytest.mark.parametrize("seed", range(3))
def test_switching_costmaps_back_and_forth_answers_as_one_switch(seed):
    """``use_costmap`` updates only the changed cells; answers are kept per costmap."""
    base = random_costmap(seed)
    rng = np.random.default_rng(seed)
    free = np.argwhere(base.cost < INSCRIBED)
    queries = [(centre(base, free[a]) + rng.uniform(-0.04, 0.04, 2), centre(base, free[b]))
               for a, b in rng.integers(0, len(free), size=(15, 2))]
    soft = base.with_obstacles(Obstacles(cylinders=(Cylinder("r", (0.5, 2.0), 0.6),)),
                               MAX_NON_OBSTACLE)
    walled = soft.with_obstacles(Obstacles(boxes=(Box("wall", (0.5, 2.0), (0.2, 3.0)),)))
    planner = GridPlanner(base)
    for costmap in (soft, walled, base, walled, soft):
        planner.use_costmap(costmap)
        factor = 1.0 + 2.0 * costmap.cost / MAX_NON_OBSTACLE
        np.testing.assert_array_equal(planner._factor.reshape(costmap.shape),
                                      np.where(costmap.traversable, factor, np.inf))
        once = GridPlanner(base)
        once.use_costmap(costmap)
        for start, goal in queries:
            answer = planner.plan(start, goal)
            expected = once.plan(start, goal)
            assert (answer.failure, answer.cost) == (expected.failure, expected.cost)
            assert answer.points.tobytes() == expected.points.tobytes()
            np.testing.assert_array_equal(answer.cells, expected.cells)
            assert planner.plan(start.copy(), goal) is answer
    with pytest.raises(ValueError):
        GridPlanner(soft).use_costmap(base)  # costs below the planner's own
