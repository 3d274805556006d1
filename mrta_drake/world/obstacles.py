"""The world's one obstacle source: static boxes and cylinders in the plane.

Walls (segments with thickness), furniture, imported map boxes and objects placed at run time
(e.g. by Scenic) all become ``Obstacles``. The plant's collision and visual geometry, the
occupancy grid (costmap, planner), the controllers' wall rays and the humans' wall forces are
all derived from it, so they can never disagree.

Frames and units: world frame, x east, y north, metres, yaw in radians about +z.
"""

import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np

from mrta_drake.stack.compiled_helper import compiled_helper
from mrta_drake.world.occupancy_grid import OccupancyGrid

_RAY_CELL = 1.0  # m, grid cell of the boxes' nearest-first order (``compiled``) ...
_RAY_TABLE = 2_000_000  # ... unless that order would have more entries than this


@dataclass(frozen=True)
class Box:
    """An upright box: ``center`` (x, y), full ``size`` (sx, sy) in its own frame rotated by
    ``yaw`` about +z, standing from z = 0 to z = ``height``."""

    name: str
    center: tuple[float, float]
    size: tuple[float, float]
    yaw: float = 0.0
    height: float = 1.0


@dataclass(frozen=True)
class Cylinder:
    """An upright cylinder of ``radius`` around ``center`` (x, y), from z = 0 to ``height``."""

    name: str
    center: tuple[float, float]
    radius: float
    height: float = 1.0


@dataclass(frozen=True, eq=False)
class Obstacles:
    """A set of static obstacles with vectorized geometric queries.

    Queries take points as arrays of shape (n, 2) and are exact for the primitives (no
    rasterization): signed distances are negative inside an obstacle.
    """

    boxes: tuple[Box, ...] = ()
    cylinders: tuple[Cylinder, ...] = ()

    def __len__(self) -> int:
        return len(self.boxes) + len(self.cylinders)

    def added(self, boxes=(), cylinders=()) -> "Obstacles":
        """A new set with more obstacles (e.g. objects placed for one run)."""
        return Obstacles(self.boxes + tuple(boxes), self.cylinders + tuple(cylinders))

    @cached_property
    def _box_arrays(self):
        if not self.boxes:
            z = np.zeros((0, 2))
            return z, z, np.zeros(0), np.zeros(0)
        centers = np.array([b.center for b in self.boxes], dtype=float)
        half = 0.5 * np.array([b.size for b in self.boxes], dtype=float)
        yaw = np.array([b.yaw for b in self.boxes], dtype=float)
        return centers, half, np.cos(yaw), np.sin(yaw)

    @cached_property
    def _cylinder_arrays(self):
        if not self.cylinders:
            return np.zeros((0, 2)), np.zeros(0)
        centers = np.array([c.center for c in self.cylinders], dtype=float)
        radii = np.array([c.radius for c in self.cylinders], dtype=float)
        return centers, radii

    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of all obstacles, m."""
        centers, half, c, s = self._box_arrays
        ext_x = np.abs(c) * half[:, 0] + np.abs(s) * half[:, 1]
        ext_y = np.abs(s) * half[:, 0] + np.abs(c) * half[:, 1]
        cc, r = self._cylinder_arrays
        lo = np.concatenate([centers - np.stack([ext_x, ext_y], 1), cc - r[:, None]])
        hi = np.concatenate([centers + np.stack([ext_x, ext_y], 1), cc + r[:, None]])
        if len(lo) == 0:
            return (0.0, 0.0, 0.0, 0.0)
        return (lo[:, 0].min(), hi[:, 0].max(), lo[:, 1].min(), hi[:, 1].max())

    def closest_points(self, points) -> tuple[np.ndarray, np.ndarray]:
        """For each point (shape (n, 2)): the closest point on any obstacle's boundary
        (shape (n, 2)) and the signed distance to it (shape (n,), negative inside).
        With no obstacles, distances are +inf and closest points equal the inputs."""
        p = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=float)))
        return closest_points_of(p, *self.compiled)

    def signed_distance(self, points) -> np.ndarray:
        """Signed distance (m) from each point (n, 2) to the nearest obstacle."""
        return self.closest_points(points)[1]

    def cast_rays(self, origins, angles, max_range: float) -> np.ndarray:
        """Distance along each ray to the first obstacle surface, capped at ``max_range``.

        ``origins`` (n, 2); ``angles`` (k,) world-frame ray directions shared by all origins or
        (n, k) per origin, radians. Returns (n, k) distances in metres. A ray starting inside
        an obstacle hits at distance 0.
        """
        o = np.ascontiguousarray(np.atleast_2d(np.asarray(origins, dtype=float)))
        ang = np.asarray(angles, dtype=float)
        if ang.ndim == 1:
            ang = np.broadcast_to(ang, (len(o), len(ang)))
        hit = np.full(ang.shape, float(max_range))
        _cast_rays_entry(o, np.cos(ang), np.sin(ang), *self.compiled, hit)
        return hit

    @cached_property
    def compiled(self) -> tuple:
        """The obstacles as the arrays compiled code takes (``closest_points_of``,
        ``cast_rays_into``): boxes (centres, half sizes, cos and sin of their yaw),
        cylinders (centres, radii), the boxes' half diagonals, then a grid (1 m cells, larger
        for very many boxes) over the boxes' bounding circles ([x_min, y_min, cell size,
        columns, rows]) and, per cell, the box indices nearest first (C, K) with a lower
        bound on their distance (m) from any point of the cell (C, K)."""
        centers, reach = self._box_arrays[0], self._box_reach
        if len(centers):
            lo = (centers - reach[:, None]).min(axis=0)
            extent = (centers + reach[:, None]).max(axis=0) - lo
            # Cells larger than 1 m where the table would pass _RAY_TABLE entries.
            cell = max(_RAY_CELL, math.sqrt(extent[0] * extent[1] * len(centers) / _RAY_TABLE))
            cols, rows = np.maximum(np.ceil(extent / cell), 1).astype(int)
        else:
            cell = _RAY_CELL
            lo, cols, rows = np.zeros(2), 0, 0
        x, y = np.meshgrid(lo[0] + cell * (np.arange(cols) + 0.5),
                           lo[1] + cell * (np.arange(rows) + 0.5))
        middles = np.column_stack([x.ravel(), y.ravel()])  # cell c = row * cols + col
        bound = (np.hypot(*(middles[:, None, :] - centers[None, :, :]).transpose(2, 0, 1))
                 - reach[None, :] - cell * math.sqrt(0.5))
        order = np.argsort(bound, axis=1, kind="stable")
        grid = np.array([lo[0], lo[1], cell, cols, rows], dtype=float)
        return (*self._box_arrays, *self._cylinder_arrays, self._box_reach, grid,
                np.ascontiguousarray(order, dtype=np.int64),
                np.ascontiguousarray(np.take_along_axis(bound, order, axis=1)))

    @cached_property
    def _box_reach(self) -> np.ndarray:
        """(K,) half diagonals of the boxes: no point of a box is farther from its centre."""
        return np.hypot(*self._box_arrays[1].T)

    def rasterize(self, bounds, resolution: float) -> OccupancyGrid:
        """An occupancy grid over ``bounds`` = (x_min, x_max, y_min, y_max) with square cells of
        ``resolution`` m; a cell is occupied when its centre lies inside an obstacle."""
        x_min, x_max, y_min, y_max = bounds
        cols = int(np.ceil((x_max - x_min) / resolution - 1e-9))
        rows = int(np.ceil((y_max - y_min) / resolution - 1e-9))
        grid = OccupancyGrid(np.zeros((rows, cols), dtype=bool), resolution, (x_min, y_min))
        occupied = grid.occupied
        for box in self.boxes:
            cy, sy = np.cos(box.yaw), np.sin(box.yaw)
            hx, hy = 0.5 * box.size[0], 0.5 * box.size[1]
            ex, ey = abs(cy) * hx + abs(sy) * hy, abs(sy) * hx + abs(cy) * hy
            self._fill(grid, box.center, (ex, ey),
                       lambda dx, dy, cy=cy, sy=sy, hx=hx, hy=hy:
                       (np.abs(cy * dx + sy * dy) <= hx) & (np.abs(-sy * dx + cy * dy) <= hy))
        for cyl in self.cylinders:
            self._fill(grid, cyl.center, (cyl.radius, cyl.radius),
                       lambda dx, dy, r=cyl.radius: dx * dx + dy * dy <= r * r)
        return OccupancyGrid(occupied, resolution, (x_min, y_min))

    @staticmethod
    def _fill(grid: OccupancyGrid, center, extent, inside) -> None:
        """Mark cells of ``grid`` whose centres satisfy ``inside(dx, dy)`` (offsets from
        ``center``), looking only at the axis-aligned ``extent`` (half widths) around it."""
        rows, cols = grid.occupied.shape
        i0, j0 = grid.world_to_cell((center[0] - extent[0], center[1] - extent[1]))
        i1, j1 = grid.world_to_cell((center[0] + extent[0], center[1] + extent[1]))
        i0, j0 = max(int(i0), 0), max(int(j0), 0)
        i1, j1 = min(int(i1), rows - 1), min(int(j1), cols - 1)
        if i0 > i1 or j0 > j1:
            return
        ii, jj = np.mgrid[i0:i1 + 1, j0:j1 + 1]
        xy = grid.cell_to_world(ii, jj)
        mask = inside(xy[..., 0] - center[0], xy[..., 1] - center[1])
        grid.occupied[i0:i1 + 1, j0:j1 + 1] |= mask


@numba.njit(cache=True)
def closest_points_of(p, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid, order,
                      bound):
    """``Obstacles.closest_points`` of points ``p`` (n, 2) for compiled code (the other
    arguments: ``Obstacles.compiled``)."""
    best_q, best_d = p.copy(), np.full(len(p), np.inf)
    _closest_points(p, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid, order,
                    bound, best_q, best_d)
    return best_q, best_d


@compiled_helper
def _box_order(x, y, grid, order, count):
    """The boxes nearest first from the point (x, y) (``Obstacles.compiled``), and the row of
    their distance bounds (-1 outside the grid: all boxes in index order, no bounds)."""
    cell, cols, rows = grid[2], int(grid[3]), int(grid[4])
    col, row = math.floor((x - grid[0]) / cell), math.floor((y - grid[1]) / cell)
    if 0 <= col < cols and 0 <= row < rows:
        return order[row * cols + col], row * cols + col
    return np.arange(count), -1


@compiled_helper
def _closest_points(p, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid, order,
                    bound, best_q, best_d):
    """``Obstacles.closest_points`` into ``best_q`` (n, 2) and ``best_d`` (n,), which start
    as the points and +inf. Boxes are looked at nearest first; those that cannot be nearer
    than the best so far are skipped; ties keep the first obstacle (boxes by index, then
    cylinders)."""
    for i in range(len(p)):
        px, py = p[i, 0], p[i, 1]
        boxes, cell = _box_order(px, py, grid, order, len(centers))
        best_k = -1
        for j in range(len(boxes)):
            if cell >= 0 and bound[cell, j] > best_d[i]:
                break
            k = boxes[j]
            dx, dy = px - centers[k, 0], py - centers[k, 1]
            hx, hy = half[k, 0], half[k, 1]
            if math.sqrt(dx * dx + dy * dy) - reach[k] > best_d[i]:
                continue
            c, s = cos[k], sin[k]
            lx, ly = c * dx + s * dy, -s * dx + c * dy
            qx, qy = min(max(lx, -hx), hx), min(max(ly, -hy), hy)
            gap_x, gap_y = hx - abs(lx), hy - abs(ly)
            if gap_x >= 0 and gap_y >= 0:  # inside: push to the nearer face
                if gap_x <= gap_y:
                    qx = (1.0 if lx >= 0 else -1.0) * hx
                else:
                    qy = (1.0 if ly >= 0 else -1.0) * hy
                sd = -min(gap_x, gap_y)
            else:
                sd = math.hypot(lx - qx, ly - qy)
            if sd < best_d[i] or (sd == best_d[i] and k < best_k):
                best_d[i], best_k = sd, k
                best_q[i, 0] = centers[k, 0] + (c * qx - s * qy)
                best_q[i, 1] = centers[k, 1] + (s * qx + c * qy)
        for k in range(len(cyl_centers)):
            dx, dy = px - cyl_centers[k, 0], py - cyl_centers[k, 1]
            dist = math.sqrt(dx * dx + dy * dy)
            sd = dist - cyl_radii[k]
            if sd < best_d[i]:
                best_d[i] = sd
                ux, uy = (dx / dist, dy / dist) if dist > 1e-12 else (1.0, 0.0)
                best_q[i, 0] = cyl_centers[k, 0] + cyl_radii[k] * ux
                best_q[i, 1] = cyl_centers[k, 1] + cyl_radii[k] * uy


@numba.njit(cache=True)
def _cast_rays_entry(o, dx, dy, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid,
                     order, bound, hit):
    """``cast_rays_into`` for Python, which cannot call a ``compiled_helper``."""
    cast_rays_into(o, dx, dy, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid,
                   order, bound, hit)


@compiled_helper
def cast_rays_into(o, dx, dy, centers, half, cos, sin, cyl_centers, cyl_radii, reach, grid,
                   order, bound, hit):
    """``Obstacles.cast_rays`` from origins ``o`` (n, 2) along unit vectors (``dx``, ``dy``)
    (n, k), for compiled code (``centers`` ... ``bound``: ``Obstacles.compiled``), into
    ``hit`` (n, k), which starts at the maximum range: slab test per box in its own frame,
    quadratic per cylinder. A ray looks at the boxes nearest first (by the origin's grid
    cell) and stops at the first that cannot be hit nearer than its nearest hit so far;
    boxes whose bounding circle (of radius ``reach``) it misses are skipped."""
    inf = math.inf
    for i in range(len(o)):
        boxes, cell = _box_order(o[i, 0], o[i, 1], grid, order, len(centers))
        for r in range(hit.shape[1]):
            ux_w, uy_w = dx[i, r], dy[i, r]
            for j in range(len(boxes)):
                if cell >= 0 and bound[cell, j] >= hit[i, r]:
                    break
                k = boxes[j]
                ddx, ddy = o[i, 0] - centers[k, 0], o[i, 1] - centers[k, 1]
                # A ray that misses the box's bounding circle misses the box.
                if (ddx * ux_w + ddy * uy_w > reach[k]
                        or abs(ddx * uy_w - ddy * ux_w) > reach[k]):
                    continue
                c, s = cos[k], sin[k]
                hx, hy = half[k, 0], half[k, 1]
                ox, oy = c * ddx + s * ddy, -s * ddx + c * ddy
                ux, uy = c * ux_w + s * uy_w, -s * ux_w + c * uy_w
                # A ray parallel to a slab is inside it for all t or for none.
                if ux == 0:
                    near_x, far_x = (-inf, inf) if abs(ox) <= hx else (inf, -inf)
                else:
                    t1, t2 = (-hx - ox) * (1.0 / ux), (hx - ox) * (1.0 / ux)
                    near_x, far_x = min(t1, t2), max(t1, t2)
                if uy == 0:
                    near_y, far_y = (-inf, inf) if abs(oy) <= hy else (inf, -inf)
                else:
                    t1, t2 = (-hy - oy) * (1.0 / uy), (hy - oy) * (1.0 / uy)
                    near_y, far_y = min(t1, t2), max(t1, t2)
                near, far = max(near_x, near_y), min(far_x, far_y)
                if near <= far and far >= 0:
                    hit[i, r] = min(hit[i, r], max(near, 0.0))
            for k in range(len(cyl_centers)):
                mx, my = o[i, 0] - cyl_centers[k, 0], o[i, 1] - cyl_centers[k, 1]
                b = mx * ux_w + my * uy_w
                disc = b * b - ((mx * mx + my * my) - cyl_radii[k] ** 2)
                if disc >= 0:
                    root = math.sqrt(disc)
                    if -b + root >= 0:
                        hit[i, r] = min(hit[i, r], max(-b - root, 0.0))
