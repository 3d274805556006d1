"""Which members of a cluster, other than its leader, get the slow-down nominal.

``all`` (the paper): every one. ``in_the_way``: only a member in conflict with an active
member ranked above it in the cluster order, i.e. within ``yield_clearance`` (m) of that
member's path ahead (its next ``yield_horizon`` m), or with that member within
``yield_clearance`` of its own path ahead, unless it drives the same way there (one follows
the other, and the barriers keep the gap); the others follow their paths, the cluster's
joint QP still keeping them all apart.
"""

from mrta_drake.control.paths import path_ahead_near, travel_direction
from mrta_drake.stack.compiled_helper import compiled_helper

FOLLOWER_RULES = ("all", "in_the_way")
NO_FOLLOWERS, ALL_FOLLOWERS, FOLLOWERS_IN_THE_WAY = 0, 1, 2  # the rules in compiled code
_SAME_WAY = 0.5  # cos 60 degrees: two directions this close are the same way


def follower_rule_code(coordination: str, followers: str) -> int:
    """The compiled code of the rule ``followers`` (one of ``FOLLOWER_RULES``) in the
    coordination mode ``coordination``: only clusters have followers."""
    if coordination != "clusters":
        return NO_FOLLOWERS
    return ALL_FOLLOWERS if followers == "all" else FOLLOWERS_IN_THE_WAY


@compiled_helper
def in_the_way(i, above, states, paths, active, clearance, horizon):
    """Whether robot i and an active robot j of ``above`` (those ranked above it in its
    cluster) are in each other's way (see the module docstring): robot states (N, 4),
    ``paths`` a ``PathArrays``, ``active`` (N,) bools, ``clearance`` and ``horizon`` m."""
    points, start, ok, _ = paths
    x, y = states[i, 0], states[i, 1]
    own = points[start[i]:start[i + 1]]
    ix, iy = travel_direction(x, y, own) if ok[i] else (0.0, 0.0)
    for j in above:
        if not active[j]:
            continue
        qx, qy = states[j, 0], states[j, 1]
        path = points[start[j]:start[j + 1]]
        near, ux, uy = path_ahead_near(qx, qy, path, x, y, horizon, clearance)
        if near and ux * ix + uy * iy < _SAME_WAY:
            return True
        if ok[i]:
            near, ux, uy = path_ahead_near(x, y, own, qx, qy, horizon, clearance)
            jx, jy = travel_direction(qx, qy, path)
            if near and ux * jx + uy * jy < _SAME_WAY:
                return True
    return False
