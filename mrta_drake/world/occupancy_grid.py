"""A 2D occupancy grid in the world frame: the raster form of the world's obstacles."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """Boolean occupancy on a regular grid in the world frame (x east, y north, metres).

    ``occupied[i, j]`` is the cell whose centre is at
    ``(origin[0] + (j + 0.5) * resolution, origin[1] + (i + 0.5) * resolution)``:
    row 0 is the southmost row (smallest y), column 0 the westmost (smallest x). Note that a
    ROS map image stores its top row first; importers flip it.
    """

    occupied: np.ndarray  # bool, shape (rows, cols); treat as read-only
    resolution: float  # m per cell side
    origin: tuple[float, float]  # world (x, y) of the lower-left corner of cell (0, 0), m

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid's area, m."""
        rows, cols = self.occupied.shape
        x0, y0 = self.origin
        return (x0, x0 + cols * self.resolution, y0, y0 + rows * self.resolution)

    def world_to_cell(self, xy) -> tuple[np.ndarray, np.ndarray]:
        """Row and column indices (int arrays) of the cells containing world points ``xy``
        (shape (..., 2)); points outside the grid give indices outside [0, shape)."""
        xy = np.asarray(xy, dtype=float)
        j = np.floor((xy[..., 0] - self.origin[0]) / self.resolution).astype(int)
        i = np.floor((xy[..., 1] - self.origin[1]) / self.resolution).astype(int)
        return i, j

    def cell_to_world(self, i, j) -> np.ndarray:
        """World (x, y) of the centres of cells (i, j), shape (..., 2)."""
        i = np.asarray(i, dtype=float)
        j = np.asarray(j, dtype=float)
        return np.stack(
            [self.origin[0] + (j + 0.5) * self.resolution,
             self.origin[1] + (i + 0.5) * self.resolution],
            axis=-1,
        )

    def contains(self, xy) -> np.ndarray:
        """True where world points ``xy`` (shape (..., 2)) fall inside the grid."""
        i, j = self.world_to_cell(xy)
        rows, cols = self.occupied.shape
        return (i >= 0) & (i < rows) & (j >= 0) & (j < cols)

    def is_free(self, xy) -> np.ndarray:
        """True where world points ``xy`` fall in a free cell; points off the grid are not free."""
        i, j = self.world_to_cell(xy)
        inside = self.contains(xy)
        rows, cols = self.occupied.shape
        free = ~self.occupied[np.clip(i, 0, rows - 1), np.clip(j, 0, cols - 1)]
        return inside & free
