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
