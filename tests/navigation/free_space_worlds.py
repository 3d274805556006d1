"""Small synthetic worlds for the navigation-derivation tests: occupancy grids carved from
free rectangles, their exact walls, and sampling along roadway edges."""

import networkx as nx
import numpy as np

from mrta_drake.world.obstacles import Box, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid
from mrta_drake.world.ros_map import merge_cells

RESOLUTION = 0.05  # m


def carved(free_rects, bounds=(-10.0, 10.0, -10.0, 10.0)) -> OccupancyGrid:
    """A grid over ``bounds`` (x_min, x_max, y_min, y_max), occupied except inside the
    ``free_rects`` (x_min, x_max, y_min, y_max), m."""
    x0, x1, y0, y1 = bounds
    cols, rows = round((x1 - x0) / RESOLUTION), round((y1 - y0) / RESOLUTION)
    occupied = np.ones((rows, cols), dtype=bool)
    grid = OccupancyGrid(occupied, RESOLUTION, (x0, y0))
    centres = grid.cell_to_world(*np.indices((rows, cols)))
    for a, b, c, d in free_rects:
        inside = ((centres[..., 0] > a) & (centres[..., 0] < b)
                  & (centres[..., 1] > c) & (centres[..., 1] < d))
        occupied[inside] = False
    return grid


def walls(grid: OccupancyGrid) -> Obstacles:
    """The occupied cells as boxes, exactly (for exact clearances)."""
    res, (x0, y0) = grid.resolution, grid.origin
    return Obstacles(tuple(
        Box(f"w{k}", center=(x0 + 0.5 * (c0 + c1) * res, y0 + 0.5 * (r0 + r1) * res),
            size=((c1 - c0) * res, (r1 - r0) * res))
        for k, (r0, r1, c0, c1) in enumerate(merge_cells(grid.occupied).tolist())))


def samples(a, b, step=0.02) -> np.ndarray:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    count = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
    return a + np.linspace(0.0, 1.0, count + 1)[:, None] * (b - a)


def edge_clearances(roadways, obstacles: Obstacles) -> dict[tuple[str, str], float]:
    """Smallest exact clearance along every roadway edge, m."""
    return {(a, b): float(obstacles.signed_distance(
        samples(roadways.nodes[a], roadways.nodes[b])).min()) for a, b in roadways.edges}


def lane_graph(roadways) -> nx.DiGraph:
    graph = nx.DiGraph()
    graph.add_nodes_from(roadways.nodes)
    graph.add_edges_from(tuple(edge) for edge in roadways.edges)
    return graph


# Corridors 2.4 m wide (y in [-1.2, 1.2] for an east-west one).
PLUS = [(-1.2, 1.2, -7.2, 7.2), (-7.2, 7.2, -1.2, 1.2)]
L_BEND = [(-1.2, 1.2, -7.2, 1.2), (-1.2, 7.2, -1.2, 1.2)]
# A wide corridor, 4 m of it only 1.3 m wide (x in [-2, 2]).
NARROWED = [(-7.2, -2.0, -1.2, 1.2), (-2.0, 2.0, -0.65, 0.65), (2.0, 7.2, -1.2, 1.2)]
