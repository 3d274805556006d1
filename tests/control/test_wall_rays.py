"""Wall rays against the world's obstacles."""

import math

import numpy as np

from mrta_drake.control.wall_rays import SensingParams, WallRays, rays_with_blockages
from mrta_drake.payloads import Blockage
from mrta_drake.world.obstacles import Box, Obstacles


def _corridor():
    return Obstacles((Box("north", (0.0, 1.5), (20.0, 0.2)),
                      Box("south", (0.0, -1.5), (20.0, 0.2))))


def test_wall_hits_world_and_body_frame_rays():
    params = SensingParams()
    states = np.array([[0.0, 0.0, 0.5, 0.0], [0.0, 0.4, 0.0, 0.0], [0.0, 1.2, 0.5, 0.0]])
    hits, mask = WallRays(_corridor(), params)(states)
    assert hits.shape == (3, 13, 2) and mask.shape == (3, 13)
    # World-frame rays 3 (90 deg) and 9 (270 deg) hit the walls' faces at y = +-1.4.
    np.testing.assert_allclose(hits[0, 3], [0.0, 1.4], atol=1e-12)
    np.testing.assert_allclose(hits[1, 9], [0.0, -1.4], atol=1e-12)
    assert not mask[0, 0] and not mask[0, 6]  # along the corridor: nothing within 10 m
    # After the rays, the closest obstacle point: the north face's foot. For the robot 0.2 m
    # from it ray 3 already sees it, so it is no wall point of its own; the others are
    # farther than closest_point_range (0.4 m) from it.
    np.testing.assert_allclose(hits[1:, 12], [[0.0, 1.4], [0.0, 1.4]], atol=1e-12)
    assert not mask[:, 12].any()
    body = SensingParams(rays_in_body_frame=True)
    hits, mask = WallRays(_corridor(), body)(states)
    direction = hits[0, 1] / np.linalg.norm(hits[0, 1])
    angle = 0.5 + math.pi / 6
    np.testing.assert_allclose(direction, [math.cos(angle), math.sin(angle)])
    # Body-frame rays at 0.5 rad + k 30 degrees pass the foot (0, 1.4) 5 mm away from the
    # robot 0.2 m from it: kept; not beyond closest_point_range, nor with a range of 0.
    np.testing.assert_allclose(hits[2, 12], [0.0, 1.4], atol=1e-12)
    assert mask[:, 12].tolist() == [False, False, True]
    assert not WallRays(_corridor(), SensingParams(rays_in_body_frame=True,
                                                    closest_point_range=0.0))(states)[1][2, 12]
    hits, mask = WallRays(None, params)(states)
    assert not mask.any()


def test_the_closest_point_is_a_wall_point_where_no_ray_sees_it():
    # A 4 cm post at 45 degrees from the robot, between the rays at 30 and 60 degrees, its
    # corner 0.325 m away; a second robot 1.1 m from it (beyond closest_point_range).
    post = Obstacles((Box("post", (0.25, 0.25), (0.04, 0.04)),))
    states = np.array([[0.0, 0.0, 0.0, 0.0], [-0.55, -0.55, 0.0, 0.0]])
    hits, mask = WallRays(post, SensingParams())(states)
    assert not mask[0, :12].any()
    np.testing.assert_allclose(hits[0, 12], [0.23, 0.23], atol=1e-12)
    assert mask[:, 12].tolist() == [True, False]
    # A blockage box across the post's line of sight: its nearer closest point replaces
    # the post's; seen by ray 0 (its foot at (0.2, 0)), it is then no wall point of its own.
    # Its closest point is the second robot's only beyond closest_point_range.
    blockage = Blockage("door", (0.2, 0.22, -1.0, 1.0), 0.0)
    hits, mask = rays_with_blockages(states, hits, mask, (blockage,), SensingParams())
    np.testing.assert_allclose(hits[0, 12], [0.2, 0.0], atol=1e-12)
    assert mask[0, 0] and not mask[:, 12].any()
    near = np.array([[-0.5, 0.3, 0.0, 0.0]])  # the box's corner 0.28 m off at 45 degrees
    hits, mask = rays_with_blockages(near, *WallRays(post, SensingParams())(near),
                                     (Blockage("box", (-0.3, -0.1, 0.5, 0.8), 0.0),),
                                     SensingParams())
    np.testing.assert_allclose(hits[0, 12], [-0.3, 0.5], atol=1e-12)
    assert mask[0, 12]


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
