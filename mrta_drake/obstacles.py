"""The world's one obstacle source: static boxes and cylinders in the plane.

Walls (segments with thickness), furniture, imported map boxes and objects placed at run time
(e.g. by Scenic) all become ``Obstacles``. The plant's collision and visual geometry, the
occupancy grid (costmap, planner), the controllers' wall rays and the humans' wall forces are
all derived from it, so they can never disagree.

Frames and units: world frame, x east, y north, metres, yaw in radians about +z.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mrta_drake.occupancy_grid import OccupancyGrid


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
        p = np.atleast_2d(np.asarray(points, dtype=float))
        n = len(p)
        best_d = np.full(n, np.inf)
        best_q = p.copy()
        centers, half, c, s = self._box_arrays
        if len(centers):
            d = p[:, None, :] - centers[None, :, :]  # (n, K, 2) world offsets
            lx = c * d[..., 0] + s * d[..., 1]  # local frame coordinates
            ly = -s * d[..., 0] + c * d[..., 1]
            qx = np.clip(lx, -half[:, 0], half[:, 0])
            qy = np.clip(ly, -half[:, 1], half[:, 1])
            outside = np.hypot(lx - qx, ly - qy)
            gap_x = half[:, 0] - np.abs(lx)
            gap_y = half[:, 1] - np.abs(ly)
            inside = (gap_x >= 0) & (gap_y >= 0)
            # Inside: push to the nearer face.
            to_x = inside & (gap_x <= gap_y)
            to_y = inside & ~to_x
            qx = np.where(to_x, np.sign(lx + (lx == 0)) * half[:, 0], qx)
            qy = np.where(to_y, np.sign(ly + (ly == 0)) * half[:, 1], qy)
            sd = np.where(inside, -np.minimum(gap_x, gap_y), outside)
            k = np.argmin(sd, axis=1)
            rows = np.arange(n)
            best_d = sd[rows, k]
            qxk, qyk = qx[rows, k], qy[rows, k]
            best_q = centers[k] + np.stack([c[k] * qxk - s[k] * qyk, s[k] * qxk + c[k] * qyk], 1)
        cc, r = self._cylinder_arrays
        if len(cc):
            d = p[:, None, :] - cc[None, :, :]
            dist = np.linalg.norm(d, axis=-1)
            sd = dist - r
            k = np.argmin(sd, axis=1)
            rows = np.arange(n)
            better = sd[rows, k] < best_d
            safe = np.maximum(dist[rows, k], 1e-12)[:, None]
            direction = np.where(dist[rows, k][:, None] > 1e-12, d[rows, k] / safe, [1.0, 0.0])
            q = cc[k] + r[k][:, None] * direction
            best_d = np.where(better, sd[rows, k], best_d)
            best_q = np.where(better[:, None], q, best_q)
        return best_q, best_d

    def signed_distance(self, points) -> np.ndarray:
        """Signed distance (m) from each point (n, 2) to the nearest obstacle."""
        return self.closest_points(points)[1]

    def cast_rays(self, origins, angles, max_range: float) -> np.ndarray:
        """Distance along each ray to the first obstacle surface, capped at ``max_range``.

        ``origins`` (n, 2); ``angles`` (k,) world-frame ray directions shared by all origins or
        (n, k) per origin, radians. Returns (n, k) distances in metres. A ray starting inside
        an obstacle hits at distance 0.
        """
        o = np.atleast_2d(np.asarray(origins, dtype=float))
        ang = np.asarray(angles, dtype=float)
        if ang.ndim == 1:
            ang = np.broadcast_to(ang, (len(o), len(ang)))
        dx, dy = np.cos(ang), np.sin(ang)  # (n, k)
        hit = np.full(ang.shape, float(max_range))
        centers, half, c, s = self._box_arrays
        if len(centers):
            d = o[:, None, :] - centers[None, :, :]  # (n, K, 2)
            ox = (c * d[..., 0] + s * d[..., 1])[:, None, :]  # (n, 1, K)
            oy = (-s * d[..., 0] + c * d[..., 1])[:, None, :]
            ux = c * dx[..., None] + s * dy[..., None]  # (n, k, K)
            uy = -s * dx[..., None] + c * dy[..., None]
            with np.errstate(divide="ignore", invalid="ignore"):
                inv_x, inv_y = 1.0 / ux, 1.0 / uy
                tx1, tx2 = (-half[:, 0] - ox) * inv_x, (half[:, 0] - ox) * inv_x
                ty1, ty2 = (-half[:, 1] - oy) * inv_y, (half[:, 1] - oy) * inv_y
            # A ray parallel to a slab is inside it for all t or for none.
            in_x = np.abs(ox) <= half[:, 0]
            in_y = np.abs(oy) <= half[:, 1]
            t_near_x = np.where(ux == 0, np.where(in_x, -np.inf, np.inf), np.minimum(tx1, tx2))
            t_far_x = np.where(ux == 0, np.where(in_x, np.inf, -np.inf), np.maximum(tx1, tx2))
            t_near_y = np.where(uy == 0, np.where(in_y, -np.inf, np.inf), np.minimum(ty1, ty2))
            t_far_y = np.where(uy == 0, np.where(in_y, np.inf, -np.inf), np.maximum(ty1, ty2))
            t_near = np.maximum(t_near_x, t_near_y)
            t_far = np.minimum(t_far_x, t_far_y)
            valid = (t_near <= t_far) & (t_far >= 0)
            t = np.where(valid, np.maximum(t_near, 0.0), np.inf)
            hit = np.minimum(hit, t.min(axis=-1))
        cc, r = self._cylinder_arrays
        if len(cc):
            m = (o[:, None, :] - cc[None, :, :])[:, None, :, :]  # (n, 1, L, 2)
            b = m[..., 0] * dx[..., None] + m[..., 1] * dy[..., None]  # (n, k, L)
            cterm = (m**2).sum(-1) - r**2
            disc = b * b - cterm
            with np.errstate(invalid="ignore"):
                root = np.sqrt(disc)
            t0, t1 = -b - root, -b + root
            valid = (disc >= 0) & (t1 >= 0)
            t = np.where(valid, np.maximum(t0, 0.0), np.inf)
            hit = np.minimum(hit, t.min(axis=-1))
        return hit

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
