"""The shared point-to-piece distances against a direct construction."""

import math

import numpy as np

from mrta_drake.world.segment_distances import distance_to_polyline, segment_distances


def _direct(p, a, b) -> float:
    """The distance from p to the piece a-b: to its nearest end, or across to the line
    where the foot of the perpendicular falls inside it."""
    ends = min(math.dist(p, a), math.dist(p, b))
    length = math.dist(a, b)
    if length == 0.0:
        return ends
    u = ((b[0] - a[0]) / length, (b[1] - a[1]) / length)
    along = (p[0] - a[0]) * u[0] + (p[1] - a[1]) * u[1]
    if 0.0 <= along <= length:
        return abs((p[0] - a[0]) * u[1] - (p[1] - a[1]) * u[0])
    return ends


def test_distances_match_a_direct_construction_for_every_point_and_piece():
    rng = np.random.default_rng(3)
    points = rng.uniform(-5, 5, (40, 2))
    starts = rng.uniform(-5, 5, (7, 2))
    ends = rng.uniform(-5, 5, (7, 2))
    ends[2] = starts[2]  # a piece of zero length is its point
    got = segment_distances(points, starts, ends)
    assert got.shape == (40, 7)
    want = [[_direct(p, a, b) for a, b in zip(starts, ends, strict=True)] for p in points]
    assert np.allclose(got, want, atol=1e-12)
    # Leading dimensions are kept: a grid of points gives a grid of rows.
    assert segment_distances(points.reshape(4, 10, 2), starts, ends).shape == (4, 10, 7)
    assert np.allclose(segment_distances(points[0], starts, ends), want[0], atol=1e-12)


def test_a_polyline_is_as_near_as_its_nearest_piece_and_a_single_point_is_a_point():
    line = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    points = np.array([[2.0, 1.0], [5.0, 1.5], [-3.0, -4.0], [4.0, 5.0]])
    assert np.allclose(distance_to_polyline(points, line), [1.0, 1.0, 5.0, 2.0])
    assert np.allclose(distance_to_polyline(points, line[:1]), np.linalg.norm(points, axis=1))
