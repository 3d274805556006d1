"""Wall rays: where a fan of rays from each robot first hits the world's obstacles (and any
blockages). The hits are the wall points of the barriers (``safety_rows``)."""

import math
from dataclasses import dataclass

import numba
import numpy as np

from mrta_drake.errors import require_non_negative, require_positive
from mrta_drake.payloads import ROBOT_STATE_SIZE
from mrta_drake.scenario.disturbances import blockage_obstacles
from mrta_drake.world.obstacles import cast_rays_into


@dataclass(frozen=True)
class SensingParams:
    """The wall rays: ``ray_count`` rays ``ray_spacing`` rad apart from ``ray_start`` (rad),
    in the world frame or, with ``rays_in_body_frame``, as offsets from the robot's heading;
    a ray sees walls up to ``ray_range`` m away."""

    ray_count: int = 12
    ray_spacing: float = math.pi / 6
    ray_start: float = 0.0
    rays_in_body_frame: bool = False
    ray_range: float = 10.0

    def __post_init__(self):
        require_non_negative(self, "ray_count")
        require_positive(self, "ray_range")

    def ray_angles(self) -> np.ndarray:
        """Ray directions (rad): world frame, or offsets from the heading in the body frame."""
        return self.ray_start + self.ray_spacing * np.arange(self.ray_count)


class WallRays:
    """Wall rays of robots against the world's ``Obstacles`` (None: no walls).

    Calling it with robot states (N, 4) returns the ray hits (N, R, 2) in the world frame and a
    mask (N, R) of rays that hit within ``ray_range``.
    """

    def __init__(self, obstacles, params: SensingParams):
        self._params = params
        self._obstacles = obstacles if obstacles is not None and len(obstacles) else None
        self._angles = params.ray_angles()

    def __call__(self, states) -> tuple[np.ndarray, np.ndarray]:
        p = self._params
        states = np.ascontiguousarray(states, dtype=float).reshape(-1, 4)
        shape = (len(states), p.ray_count)
        if self._obstacles is None or p.ray_count == 0:
            return np.zeros(shape + (2,)), np.zeros(shape, dtype=bool)
        hits, mask = np.empty(shape + (2,)), np.empty(shape, dtype=bool)
        _wall_hits(states, self._angles, p.rays_in_body_frame, float(p.ray_range),
                   self._obstacles.compiled, hits, mask)
        return hits, mask


@numba.njit(cache=True)
def _wall_hits(states, angles, in_body_frame, ray_range, obstacles, hits, mask):
    """``WallRays`` into ``hits`` (N, R, 2) and ``mask`` (N, R) (``obstacles``:
    ``Obstacles.compiled``)."""
    n, rays = len(states), len(angles)
    # Element by element: np.full and a sliced copy compile numba's generic code for each.
    origins, dx, dy, dist = (np.empty((n, 2)), np.empty((n, rays)), np.empty((n, rays)),
                             np.empty((n, rays)))
    for i in range(n):
        origins[i, 0], origins[i, 1] = states[i, 0], states[i, 1]
        for r in range(rays):
            angle = angles[r] + states[i, 2] if in_body_frame else angles[r]
            dx[i, r], dy[i, r], dist[i, r] = np.cos(angle), np.sin(angle), ray_range
    cast_rays_into(origins, dx, dy, *obstacles, dist)
    for i in range(n):
        for r in range(rays):
            hits[i, r, 0] = states[i, 0] + dist[i, r] * dx[i, r]
            hits[i, r, 1] = states[i, 1] + dist[i, r] * dy[i, r]
            mask[i, r] = dist[i, r] < ray_range


def rays_with_blockages(states, hits, mask, blockages, params: SensingParams
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Wall ray ``hits`` (N, R, 2) and ``mask`` (N, R) of robots ``states`` (N, 4) (as from
    ``WallRays``) with the rays also stopped by the boxes of ``blockages``
    (``payloads.Blockage``), except a box the robot is in: it drives out unhindered."""
    states = np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
    origins = states[:, :2]
    angles = np.broadcast_to(params.ray_angles(), (len(states), params.ray_count))
    if params.rays_in_body_frame:
        angles = angles + states[:, 2:3]
    directions = np.stack([np.cos(angles), np.sin(angles)], -1)
    reach = params.ray_range
    dist = np.where(mask, np.linalg.norm(hits - origins[:, None, :], axis=-1), reach)
    for blockage in blockages:
        near = blockage_obstacles((blockage,)).cast_rays(origins, angles, reach)
        near[blockage.contains(origins)] = reach
        nearer = near < dist
        hits = np.where(nearer[..., None], origins[:, None, :] + near[..., None] * directions,
                        hits)
        mask, dist = mask | nearer, np.minimum(dist, near)
    return hits, mask
