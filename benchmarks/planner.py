"""Plan time of the grid planner on the hospital at 0.05 m, next to peers in the same process.

Start and goal pairs are drawn (seeded) from the free cells (cost 0) of the largest
traversable component, so every pair is connected. Peers solve the same queries on the same
costmap: scikit-image's ``MCP_Geometric`` (compiled Dijkstra, same cost model), and, on the
first ``--peer-pairs`` pairs only, a pure-Python grid A* (heapq, same cost model and
heuristic, the way pure-Python robotics packages plan). ``tcod.path`` (integer costs) and
``pyastar2d`` (diagonal moves cost as much as straight ones) run too when installed; these
compiled peers may cut corners, which the planner does not. The
``cost ratio`` column is each peer's path cost under the planner's cost model divided by
the planner's optimum (1.000 = optimal).

    python benchmarks/planner.py [--map FILE] [--pairs 200] [--peer-pairs 20]

``--map`` takes a floor-plan YAML (``load_floor_plan``) or a ROS map YAML
(``read_ros_map``); by default ``models/hospital/floor_plan.yaml`` if present, else the
reference ROS map of the original hospital. Writes benchmarks/results/planner.json.
"""

import argparse
import heapq
import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mrta_drake.navigation.costmap import INSCRIBED, MAX_NON_OBSTACLE, Costmap  # noqa: E402
from mrta_drake.navigation.grid_planner import GridPlanner  # noqa: E402
from mrta_drake.world.occupancy_grid import OccupancyGrid  # noqa: E402

FLOOR_PLAN = ROOT / "models" / "hospital" / "floor_plan.yaml"
REFERENCE_MAP = ROOT.parent / "shared" / "reference" / "hospital_map" / "hospital_floor1.yaml"
RESOLUTION = 0.05


def load_grid(path: Path) -> OccupancyGrid:
    """The occupancy grid of a floor plan or ROS map YAML at 0.05 m."""
    with open(path) as f:
        is_ros_map = "image" in (yaml.safe_load(f) or {})
    if is_ros_map:
        from mrta_drake.world.ros_map import read_ros_map

        grid = read_ros_map(path)
        if not math.isclose(grid.resolution, RESOLUTION):
            raise SystemExit(f"{path}: resolution {grid.resolution} m, need {RESOLUTION} m")
        return grid
    from mrta_drake.world.floor_plan import load_floor_plan

    plan = load_floor_plan(path)
    return plan.obstacles.rasterize(plan.bounds, RESOLUTION)


def path_cost(factor: np.ndarray, cells: np.ndarray, resolution: float) -> float:
    """Cost (m) of a cell path under the planner's model."""
    f = factor[cells[:, 0], cells[:, 1]]
    step = np.hypot(*np.diff(cells, axis=0).T)
    return float(np.sum(step * 0.5 * (f[:-1] + f[1:])) * resolution)


def python_astar(factor: np.ndarray, start, goal) -> np.ndarray | None:
    """Textbook grid A* in pure Python on the planner's cost model (no corner cutting),
    octile heuristic."""
    rows, cols = factor.shape
    moves = [(di, dj, math.hypot(di, dj)) for di in (-1, 0, 1) for dj in (-1, 0, 1)
             if di or dj]
    g = {start: 0.0}
    parent = {start: None}
    closed = set()
    frontier = [(0.0, start)]
    while frontier:
        _, cell = heapq.heappop(frontier)
        if cell in closed:
            continue
        if cell == goal:
            path = []
            while cell is not None:
                path.append(cell)
                cell = parent[cell]
            return np.array(path[::-1])
        closed.add(cell)
        i, j = cell
        for di, dj, length in moves:
            ni, nj = i + di, j + dj
            if not (0 <= ni < rows and 0 <= nj < cols) or not factor[ni, nj] < math.inf:
                continue
            if di and dj and not (factor[i, nj] < math.inf and factor[ni, j] < math.inf):
                continue
            cost = g[cell] + length * 0.5 * (factor[i, j] + factor[ni, nj])
            if cost < g.get((ni, nj), math.inf):
                g[(ni, nj)] = cost
                parent[(ni, nj)] = cell
                a, b = abs(ni - goal[0]), abs(nj - goal[1])
                h = max(a, b) + (math.sqrt(2) - 1) * min(a, b)
                heapq.heappush(frontier, (cost + h, (ni, nj)))
    return None


def make_peers(factor: np.ndarray) -> dict:
    """name -> (function (start_cell, goal_cell) -> cell path or None, note)."""
    from skimage.graph import MCP_Geometric

    def mcp(start, goal):
        # MCP_Geometric charges |uv| * (cost(u) + cost(v)) / 2: the planner's model.
        mcp = MCP_Geometric(factor)
        costs, _ = mcp.find_costs([start], [goal], find_all_ends=False)
        return np.array(mcp.traceback(goal)) if np.isfinite(costs[goal]) else None

    peers = {"skimage MCP_Geometric": (mcp, "compiled Dijkstra, float costs")}
    try:
        import tcod.path

        scale = 64  # tcod takes integer costs: factor quantized to 1/64
        tcod_cost = np.where(np.isfinite(factor), np.round(scale * factor), 0).astype(np.int32)
        graph = tcod.path.SimpleGraph(cost=tcod_cost, cardinal=70, diagonal=99, greed=scale)

        def tcod_astar(start, goal):
            finder = tcod.path.Pathfinder(graph)
            finder.add_root(start)
            path = finder.path_to(goal)
            return path if len(path) and tuple(path[-1]) == goal else None

        peers["tcod Pathfinder"] = (tcod_astar, "compiled A*, integer costs (1/64)")
    except ImportError:
        pass
    try:
        import pyastar2d

        weights = np.where(np.isfinite(factor), factor, np.inf).astype(np.float32)

        def pyastar(start, goal):
            return pyastar2d.astar_path(weights, start, goal, allow_diagonal=True)

        peers["pyastar2d"] = (pyastar, "compiled A*, diagonal step costs 1")
    except ImportError:
        pass
    return peers


def timed(solve, *args):
    """``solve(*args)`` and its (CPU, wall) seconds. CPU time is the main figure: it hardly
    depends on what else the shared machine runs."""
    cpu, wall = time.process_time(), time.perf_counter()
    result = solve(*args)
    return result, time.process_time() - cpu, time.perf_counter() - wall


def summarize(cpu_s, wall_s, costs, optimum) -> dict:
    cpu_ms = np.asarray(cpu_s) * 1e3
    ratio = np.asarray(costs) / np.asarray(optimum)
    return {"pairs": len(cpu_ms), "median_ms": float(np.median(cpu_ms)),
            "p95_ms": float(np.percentile(cpu_ms, 95)), "max_ms": float(np.max(cpu_ms)),
            "median_wall_ms": float(np.median(wall_s) * 1e3),
            "mean_cost_ratio": float(np.mean(ratio)), "max_cost_ratio": float(np.max(ratio))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", type=Path,
                        default=FLOOR_PLAN if FLOOR_PLAN.exists() else REFERENCE_MAP)
    parser.add_argument("--pairs", type=int, default=200)
    parser.add_argument("--peer-pairs", type=int, default=20,
                        help="pairs for the pure-Python A* (slow)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/planner.json")
    args = parser.parse_args()

    grid = load_grid(args.map)
    tic = time.perf_counter()
    costmap = Costmap.from_grid(grid)
    costmap_s = time.perf_counter() - tic
    tic = time.perf_counter()
    planner = GridPlanner(costmap)
    planner_init_s = time.perf_counter() - tic  # landmarks (and, on a cold cache, compiling)

    traversable = costmap.traversable
    labels, _ = ndimage.label(traversable, structure=np.ones((3, 3)))
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    free = np.argwhere((labels == sizes.argmax()) & (costmap.cost == 0))
    rng = np.random.default_rng(args.seed)
    pairs = [(tuple(map(int, free[a])), tuple(map(int, free[b])))
             for a, b in rng.integers(0, len(free), size=(args.pairs, 2))]
    weight = planner.params.cost_weight
    factor = np.where(traversable, 1.0 + weight * costmap.cost / MAX_NON_OBSTACLE, np.inf)

    def world(cell):
        return grid.cell_to_world(*cell)

    # Warm up (JIT cache load) on a pair not timed: a repeated query is a remembered answer.
    planner.plan(world(pairs[0][1]), world(pairs[0][0]))
    cpu, wall, optimum, lengths = [], [], [], []
    for start, goal in pairs:
        result, cpu_s, wall_s = timed(planner.plan, world(start), world(goal))
        cpu.append(cpu_s)
        wall.append(wall_s)
        if not result.found or np.any(costmap.cost[tuple(result.cells.T)] >= INSCRIBED):
            raise SystemExit(f"planner failed on {start} -> {goal}: {result.failure}")
        optimum.append(result.cost)
        lengths.append(float(np.sum(np.linalg.norm(np.diff(result.points, axis=0), axis=1))))
    rows = {"mrta_drake GridPlanner": dict(
        summarize(cpu, wall, optimum, optimum),
        note="Numba A* + ALT landmarks, float costs; time includes shortcutting")}

    peers = make_peers(factor)
    peers["pure-Python A*"] = (lambda s, g: python_astar(factor, s, g),
                               "heapq A*, same cost model")
    for name, (solve, note) in peers.items():
        count = args.peer_pairs if name == "pure-Python A*" else len(pairs)
        peer_cpu, peer_wall, peer_costs = [], [], []
        for start, goal in pairs[:count]:
            cells, cpu_s, wall_s = timed(solve, start, goal)
            peer_cpu.append(cpu_s)
            peer_wall.append(wall_s)
            peer_costs.append(path_cost(factor, np.asarray(cells), costmap.resolution)
                              if cells is not None else math.inf)
        rows[name] = dict(summarize(peer_cpu, peer_wall, peer_costs, optimum[:count]),
                          note=note)

    print(f"map {args.map} | grid {grid.shape[0]} x {grid.shape[1]} at {grid.resolution} m | "
          f"{int(traversable.sum())} traversable cells | {len(pairs)} pairs, "
          f"mean path {np.mean(lengths):.1f} m")
    print(f"costmap {costmap_s * 1e3:.0f} ms, planner setup {planner_init_s * 1e3:.0f} ms")
    print("CPU ms per query (wall: median wall-clock ms)")
    print(f"{'planner':<24}{'pairs':>6}{'median':>9}{'p95':>9}{'max':>9}{'wall':>9}"
          f"{'cost ratio':>12}  note")
    for name, row in rows.items():
        print(f"{name:<24}{row['pairs']:>6}{row['median_ms']:>9.2f}{row['p95_ms']:>9.2f}"
              f"{row['max_ms']:>9.1f}{row['median_wall_ms']:>9.2f}"
              f"{row['mean_cost_ratio']:>12.3f}  {row['note']}")

    import numba

    args.out.parent.mkdir(parents=True, exist_ok=True)
    report = {
        "map": str(args.map.relative_to(ROOT) if args.map.is_relative_to(ROOT) else args.map),
        "grid_shape": list(grid.shape), "resolution": grid.resolution,
        "traversable_cells": int(traversable.sum()), "pairs": len(pairs), "seed": args.seed,
        "mean_path_length_m": float(np.mean(lengths)), "costmap_build_ms": costmap_s * 1e3,
        "planner_setup_ms": planner_init_s * 1e3, "results": rows,
        "python": platform.python_version(), "numpy": np.__version__,
        "numba": numba.__version__, "machine": platform.machine(),
    }
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out.relative_to(ROOT) if args.out.is_relative_to(ROOT) else args.out}")


if __name__ == "__main__":
    main()
