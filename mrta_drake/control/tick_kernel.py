"""The compiled part of one ``ClusterCbfController`` tick before its QPs: clusters and their
order, every robot's nominal input (the slow-down for followers and for robots cut off from
messages), the hard input bounds, and the smallest distances for the telemetry."""

import math
from typing import NamedTuple

import numba
import numpy as np

from mrta_drake.control.barrier_minima import min_squared_distances
from mrta_drake.control.clusters import cluster_labels, order_by_cluster
from mrta_drake.control.followers import FOLLOWERS_IN_THE_WAY, NO_FOLLOWERS, in_the_way
from mrta_drake.control.input_limits import fill_input_bounds
from mrta_drake.control.nominal import nominal_inputs, slow_down_input
from mrta_drake.stack.compiled_helper import compiled_helper


class TickSettings(NamedTuple):
    """What the kernel takes of the controller, the same every tick."""

    priorities: np.ndarray  # (N,) float; smaller leads
    gains: np.ndarray  # NominalParams.gains
    limits: np.ndarray  # input_limits.limits_of
    follower_rule: int  # followers.NO_FOLLOWERS, ALL_FOLLOWERS or FOLLOWERS_IN_THE_WAY
    yield_clearance: float  # m
    head_on_clearance: float  # m
    yield_horizon: float  # m
    cluster_radius2: float  # m^2, the cluster radius squared


class TickRobots(NamedTuple):
    """The robots at one tick, (N,) arrays unless noted."""

    states: np.ndarray  # (N, 4) [x, y, theta, v], as the controller plans from them
    shared: np.ndarray  # (N, 4) as the others know them (Disturbances.seen_by)
    keys: np.ndarray  # float, the leader rule's sort keys (smaller leads)
    active: np.ndarray  # bool, has somewhere to go
    stalled: np.ndarray  # bool, stood too long as a leader
    reachable: np.ndarray  # bool, in touch with the others (may join a cluster)
    slowed: np.ndarray  # bool, gets the slow-down nominal whatever its rank


class TickWorld(NamedTuple):
    """What the robots see at one tick: the humans and each robot's wall ray hits."""

    human_positions: np.ndarray  # (M, 2) m
    human_velocities: np.ndarray  # (M, 2) m/s
    hits: np.ndarray  # (N, R + 1, 2) m, as from WallRays: R rays, then the closest point
    hit_mask: np.ndarray  # (N, R + 1) bool


class TickArrays(NamedTuple):
    """What ``plan_tick`` makes for N robots: cluster c is
    ``order[starts[c]:starts[c + 1]]`` (leader first; robots' cluster numbers in
    ``labels``), the nominal inputs and hard bounds (N, 2) ``[a, omega]``, and the smallest
    squared distances (m^2) of a robot to its wall hits, to a human and to another robot."""

    order: np.ndarray
    labels: np.ndarray
    starts: np.ndarray
    u_nominal: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    minima: np.ndarray

    @staticmethod
    def empty(n: int) -> "TickArrays":
        """Arrays for n robots, to be filled by ``plan_tick``."""
        return TickArrays(np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
                          np.empty(n + 1, dtype=np.int64), np.empty((n, 2)), np.empty((n, 2)),
                          np.empty((n, 2)), np.empty(3))


@numba.njit(cache=True)
def plan_tick(robots, world, paths, settings, out):
    """Fills ``out`` (a ``TickArrays``) for ``robots`` (a ``TickRobots``) on their ``paths``
    (a ``PathArrays``) in ``world`` (a ``TickWorld``), with ``settings`` (a
    ``TickSettings``): clusters (``cluster_labels``, ``order_by_cluster``); the nominal inputs,
    with the heading gate of a cluster for clustered robots and passing around the robots as
    the others know them and the humans, then the slow-down for the ``slowed`` robots and
    for the followers of the follower rule; the input bounds; the smallest distances.

    Each argument may also be a plain tuple of the same fields, which numba types faster.
    """
    states, shared, keys, active, stalled, reachable, slowed = robots
    human_positions, human_velocities, hits, hit_mask = world
    (priorities, gains, limits, follower_rule, yield_clearance, head_on_clearance, yield_horizon,
     radius2) = settings
    order, labels, starts, u_nominal, lower, upper, minima = out
    n = len(states)
    _copy_into(labels, cluster_labels(states[:, :2].copy(), radius2, reachable))
    _copy_into(order, order_by_cluster(labels, active, stalled, keys, priorities))
    size = np.zeros(n, dtype=np.int64)
    for i in range(n):
        size[labels[i]] += 1
    starts[0] = 0
    for c in range(n):
        starts[c + 1] = starts[c] + size[c]
    clustered = np.empty(n, dtype=np.bool_)
    for i in range(n):
        clustered[i] = size[labels[i]] > 1
    rays = hits.shape[1] - 1  # the nominal's room to pass takes the rays in ray order only
    nominal_inputs(states, paths, clustered, _bodies(shared, human_positions, human_velocities),
                   hits[:, :rays], hit_mask[:, :rays], gains, u_nominal)
    first = 0  # position in order of the current cluster's leader
    for k in range(n):
        i = order[k]
        follower = k > 0 and labels[order[k - 1]] == labels[i]
        if not follower:
            first = k
        if follower and follower_rule == FOLLOWERS_IN_THE_WAY:
            follower = in_the_way(i, order[first:k], states, paths, active, yield_clearance,
                                  head_on_clearance, yield_horizon)
        if slowed[i] or (follower_rule != NO_FOLLOWERS and follower):
            u_nominal[i, 0], u_nominal[i, 1] = slow_down_input(states[i, 3], gains)
    fill_input_bounds(states, limits, lower, upper)
    minima[0], minima[1], minima[2] = min_squared_distances(states[:, :2].copy(), hits,
                                                            hit_mask, human_positions)


@compiled_helper
def _bodies(shared, human_positions, human_velocities):
    """The robots (as the others know them) and the humans as ``[x, y, speed]`` (N + M, 3),
    for passing."""
    n = len(shared)
    bodies = np.empty((n + len(human_positions), 3))
    for i in range(n):  # element by element: an array slice assignment costs ~8 s to compile
        bodies[i, 0], bodies[i, 1], bodies[i, 2] = shared[i, 0], shared[i, 1], abs(shared[i, 3])
    for q in range(len(human_positions)):
        bodies[n + q, 0], bodies[n + q, 1] = human_positions[q, 0], human_positions[q, 1]
        bodies[n + q, 2] = math.hypot(human_velocities[q, 0], human_velocities[q, 1])
    return bodies


@compiled_helper
def _copy_into(target, source):
    """``target[:] = source`` for 1-D arrays of equal length, without numba's slice assignment
    (broadcasting and its error messages take seconds to compile)."""
    for i in range(len(target)):
        target[i] = source[i]
