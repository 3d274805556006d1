"""Robot paths for compiled code: the fleet's paths as arrays, and the geometry along a path
that the nominal control and the followers rule share.

A path is ``points`` (k, 2), k >= 1, world frame, m: a polyline from near the robot to its
goal.
"""

import math
from typing import NamedTuple

import numba
import numpy as np

from mrta_drake.payloads import PATH_OK, FleetPaths, RobotPath
from mrta_drake.stack.compiled_helper import compiled_helper


class PathArrays(NamedTuple):
    """N robots' paths for compiled code: the points of the ``ok`` ones (``has_path``)
    concatenated in ``points`` (P, 2), robot i's at ``points[start[i]:start[i + 1]]`` (none
    without an ok path); ``ok`` and ``stop_at_end`` (N,) bools."""

    points: np.ndarray
    start: np.ndarray
    ok: np.ndarray
    stop_at_end: np.ndarray

    @staticmethod
    def of(paths) -> "PathArrays":
        """The arrays of ``paths`` (N ``RobotPath`` or None)."""
        ok = [has_path(path) for path in paths]
        start = np.zeros(len(ok) + 1, dtype=np.int64)
        start[1:] = np.cumsum([len(path.points) if good else 0
                               for path, good in zip(paths, ok, strict=True)])
        points = np.concatenate([np.zeros((0, 2))] + [
            path.points for path, good in zip(paths, ok, strict=True) if good])
        stop_at_end = np.array([good and path.stop_at_end
                                for path, good in zip(paths, ok, strict=True)], dtype=bool)
        return PathArrays(np.ascontiguousarray(points, dtype=float), start,
                          np.array(ok, dtype=bool), stop_at_end)

    def progress(self, states, arrival_radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Per robot of ``states`` (N, 4): the straight-line distance (m) to its path end
        (inf without an ``ok`` path), and whether it still has somewhere to go: an ``ok``
        path, and unless the path lets it drive on, more than ``arrival_radius`` (m) from
        its end."""
        distances, active = np.empty(len(self.ok)), np.empty(len(self.ok), dtype=bool)
        _progress(np.ascontiguousarray(states, dtype=float).reshape(-1, 4), self.points,
                  self.start, self.ok, self.stop_at_end, float(arrival_radius), distances,
                  active)
        return distances, active


def has_path(path: RobotPath | None) -> bool:
    """Whether ``path`` is an ``ok`` path of at least one point (else: slow down)."""
    return path is not None and path.status == PATH_OK and len(path.points) > 0


def robot_paths_of(paths: FleetPaths, n: int) -> tuple[RobotPath | None, ...]:
    """The N robots' paths (all None for an empty FleetPaths: nothing planned yet)."""
    if len(paths.paths) not in (0, n):
        raise ValueError(f"paths: expected {n} robot paths, got {len(paths.paths)}")
    return tuple(paths.paths) if paths.paths else (None,) * n


@numba.njit(cache=True)
def _progress(states, points, start, ok, stop_at_end, arrival_radius, distances, active):
    for i in range(len(ok)):
        if not ok[i]:
            distances[i], active[i] = math.inf, False
            continue
        end = start[i + 1] - 1
        distances[i] = math.hypot(states[i, 0] - points[end, 0], states[i, 1] - points[end, 1])
        active[i] = not (stop_at_end[i] and distances[i] <= arrival_radius)


@compiled_helper
def segment_projection(x, y, points):
    """The segment of the path ``points`` (k, 2), k >= 2, nearest (x, y) and the fraction
    along it of the nearest point."""
    nearest, best, t_nearest = 0, math.inf, 0.0
    for i in range(len(points) - 1):
        sx, sy = points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]
        length2 = max(sx * sx + sy * sy, 1e-12)
        t = min(max(((x - points[i, 0]) * sx + (y - points[i, 1]) * sy) / length2, 0.0), 1.0)
        d2 = (points[i, 0] + t * sx - x) ** 2 + (points[i, 1] + t * sy - y) ** 2
        if d2 < best:
            nearest, best, t_nearest = i, d2, t
    return nearest, t_nearest


@compiled_helper
def path_ahead_near(x, y, points, qx, qy, horizon, clearance):
    """Whether a robot at (x, y) following the path ``points`` (k, 2), k >= 1, comes within
    ``clearance`` (m) of the point (qx, qy) in its next ``horizon`` m: on the way from
    (x, y) to its projection onto the path, then along the path; and the unit direction it
    then drives in (zero if it has no length)."""
    if len(points) == 1:
        return _near_segment(qx, qy, x, y, points[0, 0], points[0, 1], clearance)
    nearest, t = segment_projection(x, y, points)
    ax = points[nearest, 0] + t * (points[nearest + 1, 0] - points[nearest, 0])
    ay = points[nearest, 1] + t * (points[nearest + 1, 1] - points[nearest, 1])
    near, ux, uy = _near_segment(qx, qy, x, y, ax, ay, clearance)
    left = horizon
    for i in range(nearest + 1, len(points)):
        if near or left <= 0.0:
            break
        bx, by = points[i, 0], points[i, 1]
        length = math.hypot(bx - ax, by - ay)
        if length > left:  # the horizon ends on this segment
            s = left / length
            bx, by = ax + s * (bx - ax), ay + s * (by - ay)
        near, ux, uy = _near_segment(qx, qy, ax, ay, bx, by, clearance)
        left -= length
        ax, ay = bx, by
    return near, ux, uy


@compiled_helper
def travel_direction(x, y, points):
    """The unit direction (zero if none) a robot at (x, y) drives in along the path
    ``points`` (k, 2), k >= 1: that of the path where it projects onto it (towards the
    point of a one-point path)."""
    if len(points) == 1:
        return _near_segment(x, y, x, y, points[0, 0], points[0, 1], 0.0)[1:]
    i, _ = segment_projection(x, y, points)
    return _near_segment(x, y, points[i, 0], points[i, 1], points[i + 1, 0], points[i + 1, 1],
                         0.0)[1:]


@compiled_helper
def _near_segment(qx, qy, ax, ay, bx, by, clearance):
    """Whether (qx, qy) is within ``clearance`` (m) of the segment from (ax, ay) to
    (bx, by), and the segment's unit direction (zero if it has no length)."""
    sx, sy = bx - ax, by - ay
    length = math.hypot(sx, sy)
    t = min(max(((qx - ax) * sx + (qy - ay) * sy) / max(length * length, 1e-12), 0.0), 1.0)
    near = math.hypot(ax + t * sx - qx, ay + t * sy - qy) < clearance
    if length < 1e-9:
        return near, 0.0, 0.0
    return near, sx / length, sy / length
