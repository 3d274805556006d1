"""A Nav2-style inflated costmap over the world's occupancy grid.

Costs follow the Nav2 inflation layer: a cell whose centre is an obstacle cell is
``LETHAL`` (254); a cell within the robot's inscribed radius of an obstacle cell centre is
``INSCRIBED`` (253); out to the inflation radius the cost decays as
``floor(252 * exp(-cost_scaling * (d - robot_radius)))``, with ``d`` the Euclidean distance (m)
between the cell's centre and the nearest obstacle cell's centre; beyond it the cost is
``FREE`` (0). A robot centred in a cell of cost ``INSCRIBED`` or more is in collision.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid

FREE = 0
MAX_NON_OBSTACLE = 252  # highest cost of a cell a robot may occupy
INSCRIBED = 253
LETHAL = 254

DEFAULT_RESOLUTION = 0.05  # m per cell, as the original Nav2 costmap
MAX_CELLS = 4_000_000  # cells of a costmap at most: 10,000 m^2 at the default resolution
_FOOTPRINTS = 256  # obstacle footprints remembered per costmap (all dropped when full)


@dataclass(frozen=True)
class CostmapParams:
    """Inflation parameters (Nav2 names in brackets).

    ``robot_radius`` (inscribed radius, m): cells closer than this to an obstacle are
    ``INSCRIBED``. ``inflation_radius`` (m): cells farther than this get ``FREE``.
    ``cost_scaling`` (``cost_scaling_factor``, 1/m): exponential decay rate of the cost.
    """

    robot_radius: float = 0.22
    inflation_radius: float = 0.5
    cost_scaling: float = 3.0

    def __post_init__(self):
        if not 0.0 <= self.robot_radius <= self.inflation_radius:
            raise ValueError("need 0 <= robot_radius <= inflation_radius")
        if self.cost_scaling < 0.0:
            raise ValueError("cost_scaling must be non-negative")


def resolution_for(bounds, max_cells: int = MAX_CELLS) -> float:
    """The costmap resolution (m per cell) for a world of ``bounds`` = (x_min, x_max,
    y_min, y_max), m: the default, or for a world so large that it would need more than
    ``max_cells`` cells, the smallest whole multiple of it that needs at most that many
    (a 320 x 250 m campus: 0.15 m), so that the costmap and the planner's per-cell arrays
    (about 120 bytes a cell) stay within half a gigabyte."""
    area = (bounds[1] - bounds[0]) * (bounds[3] - bounds[2])
    factor = max(1, math.ceil(math.sqrt(area / max_cells) / DEFAULT_RESOLUTION - 1e-9))
    return round(factor * DEFAULT_RESOLUTION, 6)


def inflation_cost(distance, robot_radius: float, inflation_radius: float,
                   cost_scaling: float, resolution: float) -> np.ndarray:
    """Nav2 inflation cost (uint8) of cells at ``distance`` (m, between cell centres) from
    the nearest obstacle cell. Like Nav2, the inflation reaches
    ``ceil(inflation_radius / resolution)`` cells."""
    d = np.asarray(distance, dtype=float)
    reach = math.ceil(inflation_radius / resolution - 1e-9) * resolution
    with np.errstate(over="ignore"):
        decay = np.floor(MAX_NON_OBSTACLE * np.exp(-cost_scaling * (d - robot_radius)))
    cost = np.where(d <= reach + 1e-9, decay, FREE)
    cost = np.where(d <= robot_radius, INSCRIBED, cost)
    cost = np.where(d == 0.0, LETHAL, cost)
    return cost.astype(np.uint8)


@dataclass(frozen=True, eq=False)
class Costmap:
    """Inflated costs (uint8, see the module docstring) on the cells of ``grid`` (world
    frame, row 0 south). Build with ``Costmap.from_grid`` or ``Costmap.from_obstacles``."""

    grid: OccupancyGrid
    params: CostmapParams
    cost: np.ndarray  # uint8, grid.shape, read-only
    distance: np.ndarray = field(repr=False)  # m to the nearest obstacle cell centre, read-only
    _footprints: dict = field(default_factory=dict, init=False, repr=False)  # ``_footprint``

    @classmethod
    def from_grid(cls, grid: OccupancyGrid, params: CostmapParams = CostmapParams()
                  ) -> "Costmap":
        """Inflate the occupied cells of ``grid``."""
        occupied = np.asarray(grid.occupied, dtype=bool)
        if occupied.any():
            # In cells, then metres, as Nav2 does.
            distance = ndimage.distance_transform_edt(~occupied) * grid.resolution
        else:
            distance = np.full(occupied.shape, np.inf)
        cost = inflation_cost(distance, params.robot_radius, params.inflation_radius,
                              params.cost_scaling, grid.resolution)
        cost.flags.writeable = False
        distance.flags.writeable = False
        return cls(grid, params, cost, distance)

    @classmethod
    def from_obstacles(cls, obstacles: Obstacles, bounds,
                       params: CostmapParams = CostmapParams(),
                       resolution: float = DEFAULT_RESOLUTION) -> "Costmap":
        """Rasterize ``obstacles`` over ``bounds`` = (x_min, x_max, y_min, y_max) (m) and
        inflate them."""
        return cls.from_grid(obstacles.rasterize(bounds, resolution), params)

    def with_obstacles(self, obstacles: Obstacles, cost: int = LETHAL) -> "Costmap":
        """This costmap with ``obstacles`` added (e.g. a region closed for a while),
        recomputed only around them: each one is rasterized (``Obstacles.rasterize``) over
        its own window of cells, reaching one cell beyond the inflation radius, and inflated
        there. Costs equal those of a costmap built with the obstacles from the start;
        ``distance`` is exact within the inflation reach of them and may overstate beyond.
        With a ``cost`` below ``LETHAL`` the obstacles' cells only cost at least that much
        (not inflated, not occupied: the new costmap shares this one's grid and distances):
        e.g. ``MAX_NON_OBSTACLE`` for a region paths avoid where they can but may cross."""
        grid, params = self.grid, self.params
        res = grid.resolution
        soft = cost < LETHAL
        occupied = grid.occupied if soft else grid.occupied.copy()
        distance = self.distance if soft else self.distance.copy()
        cost_map = self.cost.copy()
        for obstacle in (*obstacles.boxes, *obstacles.cylinders):
            footprint = self._footprint(obstacle)
            if footprint is None:
                continue
            window, raster = footprint
            if soft:
                cost_map[window] = np.where(raster, np.maximum(cost_map[window], cost),
                                            cost_map[window])
                continue
            occupied[window] |= raster
            np.minimum(distance[window], ndimage.distance_transform_edt(~raster) * res,
                       out=distance[window])
            cost_map[window] = inflation_cost(distance[window], params.robot_radius,
                                              params.inflation_radius, params.cost_scaling, res)
        cost_map.flags.writeable = False
        if soft:
            return Costmap(grid, params, cost_map, distance)
        occupied.flags.writeable = False
        distance.flags.writeable = False
        return Costmap(OccupancyGrid(occupied, res, grid.origin), params, cost_map, distance)

    def _footprint(self, obstacle: Box | Cylinder):
        """The window (row and column slices) of cells reaching one cell beyond the
        inflation radius around ``obstacle``, and which of them it covers (read-only,
        ``Obstacles.rasterize`` over the window); None if it covers no cell. Remembered, as
        the same obstacles (robots at rest) come again and again."""
        if obstacle in self._footprints:
            return self._footprints[obstacle]
        grid = self.grid
        res = grid.resolution
        rows, cols = self.shape
        reach = math.ceil(self.params.inflation_radius / res - 1e-9) + 1
        part = (Obstacles(boxes=(obstacle,)) if isinstance(obstacle, Box)
                else Obstacles(cylinders=(obstacle,)))
        x_min, x_max, y_min, y_max = part.bounds()
        i0, j0 = grid.world_to_cell((x_min, y_min))
        i1, j1 = grid.world_to_cell((x_max, y_max))
        i0, j0 = max(int(i0) - reach, 0), max(int(j0) - reach, 0)
        i1, j1 = min(int(i1) + reach, rows - 1), min(int(j1) + reach, cols - 1)
        footprint = None
        if i0 <= i1 and j0 <= j1:  # else off the grid
            x0, y0 = grid.origin[0] + j0 * res, grid.origin[1] + i0 * res
            raster = part.rasterize((x0, x0 + (j1 + 1 - j0) * res, y0,
                                     y0 + (i1 + 1 - i0) * res), res).occupied
            if raster.any():
                raster.flags.writeable = False
                footprint = (slice(i0, i1 + 1), slice(j0, j1 + 1)), raster
        if len(self._footprints) == _FOOTPRINTS:
            self._footprints.clear()
        self._footprints[obstacle] = footprint
        return footprint

    @property
    def shape(self) -> tuple[int, int]:
        return self.cost.shape

    @property
    def resolution(self) -> float:
        return self.grid.resolution

    @property
    def traversable(self) -> np.ndarray:
        """True for cells a robot's centre may occupy (cost below ``INSCRIBED``)."""
        return self.cost < INSCRIBED

    def cost_at(self, xy) -> np.ndarray:
        """Cost of the cells containing world points ``xy`` (shape (..., 2)); ``LETHAL`` off
        the grid."""
        i, j = self.grid.world_to_cell(xy)
        rows, cols = self.cost.shape
        inside = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        cost = self.cost[np.clip(i, 0, rows - 1), np.clip(j, 0, cols - 1)]
        return np.where(inside, cost, LETHAL).astype(np.uint8)

    def is_traversable(self, xy) -> np.ndarray:
        """True where a robot centred at world points ``xy`` (shape (..., 2)) is clear of the
        inscribed zone and on the grid."""
        return self.cost_at(xy) < INSCRIBED
