"""The telemetry's smallest barrier values: how near the robots came to walls, people and
each other at one tick, whatever the controller."""

import math

import numba
import numpy as np

from mrta_drake.control.barriers import SafetyDistances
from mrta_drake.stack.compiled_helper import compiled_helper


def barrier_minima(states, hits, hit_mask, human_positions,
                   distances: SafetyDistances) -> tuple[float, float, float]:
    """Smallest barrier value h = |r|^2 - d^2 (m^2; inf when none) over all robots ``states``
    (N, 4) and their wall ``hits`` (N, R, 2) where ``hit_mask``, over all robot-human pairs
    and over all robot pairs (d: the safety ``distances``)."""
    p = np.ascontiguousarray(np.asarray(states, dtype=float).reshape(-1, 4)[:, :2])
    wall, human, robot = _min_squared_distances_entry(
        p, np.ascontiguousarray(hits, dtype=float).reshape(len(p), -1, 2),
        np.ascontiguousarray(hit_mask, dtype=bool).reshape(len(p), -1),
        np.ascontiguousarray(human_positions, dtype=float).reshape(-1, 2))
    return wall - distances.wall**2, human - distances.human**2, robot - distances.robot**2


@numba.njit(cache=True)
def _min_squared_distances_entry(p, hits, mask, humans):
    """``min_squared_distances`` for Python, which cannot call a ``compiled_helper``."""
    return min_squared_distances(p, hits, mask, humans)


@compiled_helper
def min_squared_distances(p, hits, mask, humans):
    """Smallest squared distance (m^2; inf when none) from a robot (p (N, 2)) to one of its
    wall ``hits`` (N, R, 2) where ``mask``, to a human (``humans`` (M, 2)), to another
    robot, compiled."""
    wall = human = robot = math.inf
    for i in range(len(p)):
        for r in range(mask.shape[1]):
            if mask[i, r]:
                wall = min(wall, (hits[i, r, 0] - p[i, 0]) ** 2 + (hits[i, r, 1] - p[i, 1]) ** 2)
        for q in range(len(humans)):
            human = min(human, (p[i, 0] - humans[q, 0]) ** 2 + (p[i, 1] - humans[q, 1]) ** 2)
        for j in range(i + 1, len(p)):
            robot = min(robot, (p[i, 0] - p[j, 0]) ** 2 + (p[i, 1] - p[j, 1]) ** 2)
    return wall, human, robot
