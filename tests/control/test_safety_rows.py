"""The safety rows of one QP."""

import math

import numpy as np
import pytest

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.safety_rows import HUMAN, ROBOT, WALL, safety_rows
from mrta_drake.control.wall_rays import WallRays
from mrta_drake.world.obstacles import Box, Obstacles


def _corridor():
    return Obstacles((Box("north", (0.0, 1.5), (20.0, 0.2)),
                      Box("south", (0.0, -1.5), (20.0, 0.2))))


def test_cluster_rows_use_each_members_own_state():
    params = CbfParams()
    states = np.array([[0.0, 0.0, 0.0, 1.0], [3.0, 1.0, math.pi / 2, 0.5]])
    hits, mask = WallRays(_corridor(), params.sensing)(states)
    humans = np.array([[1.0, -1.0]])
    rows = safety_rows(states, hits, mask, humans, np.array([[0.5, 0.0]]), np.zeros((0, 4)),
                       params)
    assert set(rows.kind) == {WALL, HUMAN, ROBOT}
    # The rays' points at the wall distance (0.6 m), the closest point (after the 12 rays)
    # at the contact guard.
    wall2 = np.append(np.full(params.sensing.ray_count, 0.36),
                      params.safety_distances.wall_contact**2)
    for member in range(2):
        mine = (rows.kind != ROBOT) & (np.abs(rows.G[:, 2 * member:2 * member + 2]).sum(1) > 0)
        other = 1 - member
        assert not np.any(rows.G[mine, 2 * other:2 * other + 2])
        mine_h = np.sort(rows.h[mine])
        expected = np.concatenate([
            np.sum((hits[member][mask[member]] - states[member, :2]) ** 2, 1)
            - wall2[mask[member]],
            np.sum((humans - states[member, :2]) ** 2, 1) - 0.36])
        np.testing.assert_allclose(mine_h, np.sort(expected))
    (pair,) = np.flatnonzero(rows.kind == ROBOT)
    assert np.all(rows.G[pair] != 0.0)
    assert rows.h[pair] == pytest.approx(10.0 - 0.36)
