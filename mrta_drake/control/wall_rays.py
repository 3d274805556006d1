"""Wall rays: where a fan of rays from each robot first hits the world's obstacles (and any
blockages), and the robot's closest obstacle point. These are the wall points of the barriers
(``safety_rows``)."""

import math
from dataclasses import dataclass

import numba
import numpy as np

from mrta_drake.errors import require_non_negative, require_positive
from mrta_drake.payloads import ROBOT_STATE_SIZE
from mrta_drake.scenario.disturbances import blockage_obstacles
from mrta_drake.stack.compiled_helper import compiled_helper
from mrta_drake.world.obstacles import cast_rays_into, closest_points_of

_SAME_POINT = 1e-3  # m; a closest point this near a ray's hit is that hit (_drop_seen_closest)


@dataclass(frozen=True)
class SensingParams:
    """The wall rays: ``ray_count`` rays ``ray_spacing`` rad apart from ``ray_start`` (rad),
    in the world frame or, with ``rays_in_body_frame``, as offsets from the robot's heading;
    a ray sees walls up to ``ray_range`` m away.

    Besides the paper's rays, each robot also sees its closest obstacle point (world frame,
    m) when it is nearer than ``closest_point_range`` m (0: never) and no ray sees it: the
    end of a thin wall (a divider, a door jamb) lying between two rays 30 degrees apart is
    seen by no ray until the robot is on it (the Open-RMF office demo: robots 4-14 cm into a
    divider's end while rounding it or backing past it, docs/control.md "The closest wall
    point"). It is an extra wall point after the rays (hits column ``ray_count``), kept at
    its own, smaller distance (``SafetyDistances.wall_contact``), a contact guard; the
    nominal controller's room to pass uses the rays only (``plan_tick``). Where a ray's hit
    is the closest point (a wall square to a ray) it is no point of its own.

    ``closest_point_range`` (0.4 m) is the demo robots' 0.22 m radius plus 0.18 m: the guard
    row (0.3 m) appears 0.1 m before it binds, room enough to brake from 0.45 m/s at the
    1 m/s^2 limit (0.1 m); and the hospital soak's robots never come that near a wall (their
    centres stay at least 0.436 m away on seeds 101-108 and 115), so that the guard touches
    only near-contacts and leaves runs that keep clear of walls as they were. A robot
    closing on the point at speed u (its speed along the direction to the point, m/s) sees
    it from ``closest_point_range`` + u^2 / (2 ``closest_point_braking``) (m/s^2; 0: a fixed
    range): braking room at any speed (the office's divider end was met at 0.74 m/s), while
    robots driving along a wall (u ~ 0) keep the fixed range."""

    ray_count: int = 12
    ray_spacing: float = math.pi / 6
    ray_start: float = 0.0
    rays_in_body_frame: bool = False
    ray_range: float = 10.0
    closest_point_range: float = 0.4
    closest_point_braking: float = 1.0

    def __post_init__(self):
        require_non_negative(self, "ray_count", "closest_point_range", "closest_point_braking")
        require_positive(self, "ray_range")

    def ray_angles(self) -> np.ndarray:
        """Ray directions (rad): world frame, or offsets from the heading in the body frame."""
        return self.ray_start + self.ray_spacing * np.arange(self.ray_count)


class WallRays:
    """Wall rays of robots against the world's ``Obstacles`` (None: no walls).

    Calling it with robot states (N, 4) returns the wall points (N, R + 1, 2) in the world
    frame, the R ray hits then the closest obstacle point, and a mask (N, R + 1) of those
    within ``ray_range`` (the closest point only within ``SensingParams.closest_point_range``
    and not where a ray's hit is the same point).
    A robot at exactly the pose of the call before (position, and heading for rays in the
    body frame) gets that call's points again without casting its rays (robots standing
    still: about a third of them in the benchmark fleets).
    """

    def __init__(self, obstacles, params: SensingParams):
        self._params = params
        self._obstacles = obstacles if obstacles is not None and len(obstacles) else None
        self._angles = params.ray_angles()
        self._last = (np.zeros((0, 4)), np.zeros((0, params.ray_count + 1, 2)),
                      np.zeros((0, params.ray_count + 1), dtype=bool))

    def __call__(self, states) -> tuple[np.ndarray, np.ndarray]:
        p = self._params
        states = np.ascontiguousarray(states, dtype=float).reshape(-1, 4)
        shape = (len(states), p.ray_count + 1)
        if self._obstacles is None:
            return np.zeros(shape + (2,)), np.zeros(shape, dtype=bool)
        hits, mask = np.empty(shape + (2,)), np.empty(shape, dtype=bool)
        _wall_hits(states, self._angles, p.rays_in_body_frame, float(p.ray_range),
                   float(p.closest_point_range), float(p.closest_point_braking),
                   self._obstacles.compiled, hits, mask,
                   *self._last)
        self._last = (states.copy(), hits.copy(), mask.copy())  # callers may write theirs
        return hits, mask


@numba.njit(cache=True)
def _wall_hits(states, angles, in_body_frame, ray_range, closest_range, braking, obstacles,
               hits, mask, last_states, last_hits, last_mask):
    """``WallRays`` into ``hits`` (N, R + 1, 2) and ``mask`` (N, R + 1) (``obstacles``:
    ``Obstacles.compiled``; ``closest_range``, ``braking``: ``SensingParams.closest_point_range``,
    ``closest_point_braking``); robot i's
    rays and closest point are cast only if its pose differs from
    ``last_states[i]`` (its hits and mask are else ``last_hits[i]``, ``last_mask[i]``;
    fewer last rows: no pose to compare)."""
    n, rays = len(states), len(angles)
    moved = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        if not (i < len(last_states) and _same(states[i, 0], last_states[i, 0])
                and _same(states[i, 1], last_states[i, 1])
                and (not in_body_frame or _same(states[i, 2], last_states[i, 2]))):
            moved[count] = i
            count += 1
            continue
        for r in range(rays + 1):
            hits[i, r, 0], hits[i, r, 1] = last_hits[i, r, 0], last_hits[i, r, 1]
            mask[i, r] = last_mask[i, r]
    # Element by element: np.full and a sliced copy compile numba's generic code for each.
    origins, dx, dy, dist = (np.empty((count, 2)), np.empty((count, rays)),
                             np.empty((count, rays)), np.empty((count, rays)))
    for a in range(count):
        i = moved[a]
        origins[a, 0], origins[a, 1] = states[i, 0], states[i, 1]
        for r in range(rays):
            angle = angles[r] + states[i, 2] if in_body_frame else angles[r]
            dx[a, r], dy[a, r], dist[a, r] = np.cos(angle), np.sin(angle), ray_range
    cast_rays_into(origins, dx, dy, *obstacles, dist)
    closest, clearance = closest_points_of(origins, *obstacles)
    for a in range(count):
        i = moved[a]
        for r in range(rays):
            hits[i, r, 0] = states[i, 0] + dist[a, r] * dx[a, r]
            hits[i, r, 1] = states[i, 1] + dist[a, r] * dy[a, r]
            mask[i, r] = dist[a, r] < ray_range
        hits[i, rays, 0], hits[i, rays, 1] = closest[a, 0], closest[a, 1]
        gate = closest_range
        if closest_range > 0.0 and braking > 0.0 and clearance[a] > 0.0:
            toward = states[i, 3] * ((closest[a, 0] - states[i, 0]) * np.cos(states[i, 2])
                                     + (closest[a, 1] - states[i, 1]) * np.sin(states[i, 2])
                                     ) / clearance[a]
            if toward > 0.0:
                gate += toward * toward / (2.0 * braking)
        mask[i, rays] = clearance[a] < min(gate, ray_range)
    _drop_seen_closest(hits, mask, moved[:count])


@numba.njit(cache=True)
def _drop_seen_closest(hits, mask, robots):
    """Unmasks the closest point (the last column of ``hits`` (N, R + 1, 2), ``mask``
    (N, R + 1)) of each robot in ``robots`` whose rays already see it: a ray's hit within
    ``_SAME_POINT`` of it. That ray's row (same point, the larger distance ``wall``: the same
    ``G``, a larger ``b``) implies the closest point's, which would only add a redundant row
    to the QP (and move the solver's answer in its last digits). The foot of the
    perpendicular on a straight wall lies on a ray whenever the wall is square to that ray
    (world-frame rays along the axes, axis-aligned walls), so this drops the closest point
    of a robot beside a straight wall (56 % of the robot-ticks of hospital soak seed 101's
    first 1250 s) and keeps it at wall ends, corners and furniture between rays."""
    rays = hits.shape[1] - 1
    for i in robots:
        for r in range(rays):
            if (mask[i, rays] and mask[i, r]
                    and abs(hits[i, r, 0] - hits[i, rays, 0]) <= _SAME_POINT
                    and abs(hits[i, r, 1] - hits[i, rays, 1]) <= _SAME_POINT):
                mask[i, rays] = False


@compiled_helper
def _same(a, b):
    """Whether ``a`` and ``b`` are the same number, the sign of a zero included."""
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


def rays_with_blockages(states, hits, mask, blockages, params: SensingParams
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Wall points ``hits`` (N, R + 1, 2) and ``mask`` (N, R + 1) of robots ``states`` (N, 4)
    (as from ``WallRays``) with the rays also stopped by the boxes of ``blockages``
    (``payloads.Blockage``) and the closest point moved onto a nearer box, except a box the
    robot is in: it drives out unhindered."""
    states = np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
    origins = states[:, :2]
    angles = np.broadcast_to(params.ray_angles(), (len(states), params.ray_count))
    if params.rays_in_body_frame:
        angles = angles + states[:, 2:3]
    directions = np.stack([np.cos(angles), np.sin(angles)], -1)
    reach = params.ray_range
    dist = np.where(mask, np.linalg.norm(hits - origins[:, None, :], axis=-1), reach)
    rays = params.ray_count
    for blockage in blockages:
        box = blockage_obstacles((blockage,))
        near = np.empty_like(dist)
        near[:, :rays] = box.cast_rays(origins, angles, reach)
        closest, near[:, rays] = box.closest_points(origins)
        near[near[:, rays] >= params.closest_point_range, rays] = reach
        near[blockage.contains(origins)] = reach
        nearer = near < dist
        points = np.concatenate([origins[:, None, :] + near[:, :rays, None] * directions,
                                 closest[:, None, :]], axis=1)
        hits = np.where(nearer[..., None], points, hits)
        mask, dist = mask | nearer, np.minimum(dist, near)
    _drop_seen_closest(hits, mask, np.arange(len(states)))
    return hits, mask
