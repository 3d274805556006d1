"""Clearance of free space: the distance from world points to the nearest obstacle.

The lane and location derivations take clearance as any function from world points (k, 2)
(x east, y north, m) to distances (k,) in m, e.g. ``Obstacles.signed_distance`` (exact for a
floor plan's boxes) or a ``ClearanceField`` (a distance transform of an occupancy grid).
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from mrta_drake.world.occupancy_grid import OccupancyGrid

Clearance = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class ClearanceField:
    """Distance (m) from each free cell of ``grid`` to the nearest occupied cell: from the
    cell's centre to the near side of that cell (the distance between the two centres less
    half a cell; exact along a row or column, within 0.21 cells otherwise). Occupied cells
    and points off the grid have clearance 0."""

    grid: OccupancyGrid
    distance: np.ndarray  # (rows, cols), m, read-only

    @classmethod
    def from_grid(cls, grid: OccupancyGrid) -> "ClearanceField":
        occupied = np.asarray(grid.occupied, dtype=bool)
        if occupied.any():
            centres = ndimage.distance_transform_edt(~occupied) * grid.resolution
            distance = np.where(occupied, 0.0, centres - 0.5 * grid.resolution)
        else:
            distance = np.full(occupied.shape, np.inf)
        distance.flags.writeable = False
        return cls(grid, distance)

    def __call__(self, points) -> np.ndarray:
        """Clearance (m) of the cells containing world points ``points`` (k, 2)."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        i, j = self.grid.world_to_cell(points)
        rows, cols = self.distance.shape
        inside = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        values = self.distance[np.clip(i, 0, rows - 1), np.clip(j, 0, cols - 1)]
        return np.where(inside, values, 0.0)


def segment_samples(start, end, step: float) -> np.ndarray:
    """Points (k, 2) from ``start`` to ``end`` (both included), at most ``step`` m apart."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    count = max(int(np.ceil(np.linalg.norm(end - start) / step)), 1)
    return start + np.linspace(0.0, 1.0, count + 1)[:, None] * (end - start)


def segment_clearance(clearance: Clearance, start, end, step: float) -> float:
    """Smallest clearance (m) at points at most ``step`` m apart along the segment from
    ``start`` to ``end``."""
    return float(np.min(clearance(segment_samples(start, end, step))))
