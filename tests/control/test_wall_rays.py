"""Wall rays against the world's obstacles."""

import math

import numpy as np

from mrta_drake.control.wall_rays import SensingParams, WallRays
from mrta_drake.world.obstacles import Box, Obstacles


def _corridor():
    return Obstacles((Box("north", (0.0, 1.5), (20.0, 0.2)),
                      Box("south", (0.0, -1.5), (20.0, 0.2))))


def test_wall_hits_world_and_body_frame_rays():
    params = SensingParams()
    states = np.array([[0.0, 0.0, 0.5, 0.0], [0.0, 0.4, 0.0, 0.0]])
    hits, mask = WallRays(_corridor(), params)(states)
    assert hits.shape == (2, 12, 2) and mask.shape == (2, 12)
    # World-frame rays 3 (90 deg) and 9 (270 deg) hit the walls' faces at y = +-1.4.
    np.testing.assert_allclose(hits[0, 3], [0.0, 1.4], atol=1e-12)
    np.testing.assert_allclose(hits[1, 9], [0.0, -1.4], atol=1e-12)
    assert not mask[0, 0] and not mask[0, 6]  # along the corridor: nothing within 10 m
    body = SensingParams(rays_in_body_frame=True)
    hits, mask = WallRays(_corridor(), body)(states)
    direction = hits[0, 1] / np.linalg.norm(hits[0, 1])
    angle = 0.5 + math.pi / 6
    np.testing.assert_allclose(direction, [math.cos(angle), math.sin(angle)])
    hits, mask = WallRays(None, params)(states)
    assert not mask.any()


def test_robots_at_their_last_pose_get_the_hits_of_fresh_rays():
    rng = np.random.default_rng(3)
    for body_frame in (False, True):
        params = SensingParams(rays_in_body_frame=body_frame)
        rays, states = WallRays(_corridor(), params), rng.uniform(-1.0, 1.0, (5, 4))
        for _ in range(6):
            moved = rng.random(len(states)) < 0.5
            states = states.copy()
            states[moved, :2] += rng.uniform(-0.3, 0.3, (int(moved.sum()), 2))
            states[~moved, 2] += rng.uniform(-0.5, 0.5, int((~moved).sum()))  # turns only
            hits, mask = rays(states)
            fresh_hits, fresh_mask = WallRays(_corridor(), params)(states)
            np.testing.assert_array_equal(hits, fresh_hits)
            np.testing.assert_array_equal(mask, fresh_mask)
        assert len(rays(states[:3])[0]) == 3  # a smaller fleet: rays cast afresh
