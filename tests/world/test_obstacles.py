"""Ray casting against the world's obstacles: the nearest-first box order per grid cell
finds exactly the hits of testing every box."""

import math

import numpy as np
import pytest

from mrta_drake.world import obstacles as obstacles_module
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles


def _reference_hits(obstacles: Obstacles, origins, angles, reach) -> np.ndarray:
    """Every ray against every box and cylinder, by the geometry alone."""
    hits = np.full((len(origins), len(angles)), reach)
    for i, (x, y) in enumerate(origins):
        for r, angle in enumerate(angles):
            d = np.array([math.cos(angle), math.sin(angle)])
            for box in obstacles.boxes:
                c, s = math.cos(box.yaw), math.sin(box.yaw)
                rotate = np.array([[c, s], [-s, c]])
                o = rotate @ (np.array([x, y]) - box.center)
                u = rotate @ d
                near, far = -math.inf, math.inf
                for axis in range(2):
                    half = 0.5 * box.size[axis]
                    if abs(u[axis]) < 1e-15:
                        if abs(o[axis]) > half:
                            near, far = math.inf, -math.inf
                        continue
                    t1, t2 = (-half - o[axis]) / u[axis], (half - o[axis]) / u[axis]
                    near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
                if near <= far and far >= 0:
                    hits[i, r] = min(hits[i, r], max(near, 0.0))
            for cylinder in obstacles.cylinders:
                m = np.array([x, y]) - cylinder.center
                b = m @ d
                disc = b * b - (m @ m - cylinder.radius ** 2)
                if disc >= 0 and -b + math.sqrt(disc) >= 0:
                    hits[i, r] = min(hits[i, r], max(-b - math.sqrt(disc), 0.0))
    return hits


def _random_world(rng, boxes: int) -> Obstacles:
    return Obstacles(tuple(Box(f"b{k}", tuple(rng.uniform(-10, 10, 2)),
                               tuple(rng.uniform(0.1, 3, 2)), float(rng.uniform(-3, 3)))
                           for k in range(boxes)), (Cylinder("c", (1.0, -2.0), 0.4),))


@pytest.mark.parametrize("table", [2_000_000, 50])
def test_rays_hit_what_testing_every_box_hits(monkeypatch, table):
    """Origins inside the grid, outside it and inside boxes; with a table small enough that
    the cells grow beyond 1 m too."""
    monkeypatch.setattr(obstacles_module, "_RAY_TABLE", table)
    rng = np.random.default_rng(3)
    world = _random_world(rng, 40)
    origins = np.vstack([rng.uniform(-12, 12, (60, 2)), [[40.0, 0.0], [0.0, -40.0]]])
    angles = np.linspace(0, 2 * math.pi, 16, endpoint=False)
    got = world.cast_rays(origins, angles, 10.0)
    np.testing.assert_allclose(got, _reference_hits(world, origins, angles, 10.0),
                               rtol=0, atol=1e-9)
    if table == 50:
        assert world.compiled[-3][2] > 1.0  # the cells did grow


def test_rays_without_boxes_reach_their_range():
    world = Obstacles()
    assert world.cast_rays([[0.0, 0.0]], [0.0, 1.0], 5.0).tolist() == [[5.0, 5.0]]


@pytest.mark.parametrize("table", [2_000_000, 50])
def test_closest_points_are_those_of_testing_every_box(monkeypatch, table):
    """The nearest-first order finds the nearest obstacle, the first one on ties (a point
    on the line between two equal boxes)."""
    monkeypatch.setattr(obstacles_module, "_RAY_TABLE", table)
    rng = np.random.default_rng(4)
    world = _random_world(rng, 40)
    twins = Obstacles((Box("left", (-1.0, 0.0), (1.0, 1.0)), Box("right", (1.0, 0.0), (1.0, 1.0))))
    points = np.vstack([rng.uniform(-12, 12, (80, 2)), [[40.0, 3.0]]])
    for obstacles, where in ((world, points), (twins, [[0.0, 0.0], [0.0, 2.0]])):
        q, d = obstacles.closest_points(where)
        singles = [Obstacles((box,)).closest_points(where) for box in obstacles.boxes] + [
            Obstacles((), (c,)).closest_points(where) for c in obstacles.cylinders]
        distances = np.array([s[1] for s in singles])
        first = np.argmin(distances, axis=0)  # argmin keeps the first on ties
        np.testing.assert_array_equal(d, distances[first, np.arange(len(d))])
        np.testing.assert_array_equal(q, np.array([singles[k][0][i] for i, k in
                                                   enumerate(first)]))
