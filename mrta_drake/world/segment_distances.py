"""Distances from points to straight pieces (line segments) and polylines in the plane: the
one rule every user shares (lanes, walls, ways in, the watchdog's spots). Metres, in any
one frame."""

import numpy as np


def segment_distances(points, starts, ends) -> np.ndarray:
    """Distance (m) from each of ``points`` (..., 2) to each straight piece from ``starts``
    (S, 2) to ``ends`` (S, 2): shape (..., S). A piece of zero length is its point."""
    points = np.asarray(points, dtype=float)
    a = np.asarray(starts, dtype=float).reshape(-1, 2)
    ab = np.asarray(ends, dtype=float).reshape(-1, 2) - a
    rel = points[..., None, :] - a
    f = np.clip((rel * ab).sum(axis=-1) / np.maximum((ab * ab).sum(axis=1), 1e-18), 0.0, 1.0)
    return np.linalg.norm(rel - f[..., None] * ab, axis=-1)


def distance_to_polyline(points, polyline) -> np.ndarray:
    """Distance (m) from each of ``points`` (..., 2) to the polyline (P, 2) (a point if
    P = 1)."""
    points = np.asarray(points, dtype=float)
    polyline = np.asarray(polyline, dtype=float).reshape(-1, 2)
    if len(polyline) == 1:
        return np.linalg.norm(points - polyline[0], axis=-1)
    return segment_distances(points, polyline[:-1], polyline[1:]).min(axis=-1)
