"""Which members of a cluster, other than its leader, get the slow-down nominal.

``all`` (the paper): every one. ``in_the_way``: only a member in conflict with an active
member ranked above it in the cluster order, i.e. within ``yield_clearance`` (m) of that
member's path ahead (its next ``yield_horizon`` m), or with that member within
``yield_clearance`` of its own path ahead, unless it drives the same way there (one follows
the other, and the barriers keep the gap). Where the two drive opposite ways there (head on,
within 60 degrees), one at least ``head_on_clearance`` (m, below ``yield_clearance``: an
option, ``CoordinationParams``) beside the other's path is not in its way: with 0.75 m,
robots on the two one-way lanes of a corridor (0.9 m apart, ``LaneParams.offset``) pass
each other, their barriers (``SafetyDistances.robot``, 0.6 m) met without either turning
aside, while two on one line, who cannot pass, are in each other's way as before. The
others follow their paths, the cluster's joint QP still keeping them all apart.
"""

from mrta_drake.control.paths import path_ahead_near, travel_direction
from mrta_drake.stack.compiled_helper import compiled_helper

FOLLOWER_RULES = ("all", "in_the_way")
NO_FOLLOWERS, ALL_FOLLOWERS, FOLLOWERS_IN_THE_WAY = 0, 1, 2  # the rules in compiled code
_SAME_WAY = 0.5  # cos 60 degrees: two directions this close are the same way
_HEAD_ON = -_SAME_WAY  # and this close to opposite, head on


def follower_rule_code(coordination: str, followers: str) -> int:
    """The compiled code of the rule ``followers`` (one of ``FOLLOWER_RULES``) in the
    coordination mode ``coordination``: only clusters have followers."""
    if coordination != "clusters":
        return NO_FOLLOWERS
    return ALL_FOLLOWERS if followers == "all" else FOLLOWERS_IN_THE_WAY


@compiled_helper
def in_the_way(i, above, states, paths, active, clearance, head_on_clearance, horizon):
    """Whether robot i and an active robot j of ``above`` (those ranked above it in its
    cluster) are in each other's way (see the module docstring): robot states (N, 4),
    ``paths`` a ``PathArrays``, ``active`` (N,) bools, ``clearance``, ``head_on_clearance``
    (at most ``clearance``) and ``horizon`` m."""
    points, start, ok, _ = paths
    x, y = states[i, 0], states[i, 1]
    own = points[start[i]:start[i + 1]]
    ix, iy = travel_direction(x, y, own) if ok[i] else (0.0, 0.0)
    for j in above:
        if not active[j]:
            continue
        qx, qy = states[j, 0], states[j, 1]
        path = points[start[j]:start[j + 1]]
        if _conflict(qx, qy, path, x, y, ix, iy, clearance, head_on_clearance, horizon):
            return True
        if ok[i]:
            jx, jy = travel_direction(qx, qy, path)
            if _conflict(x, y, own, qx, qy, jx, jy, clearance, head_on_clearance, horizon):
                return True
    return False


@compiled_helper
def _conflict(x, y, points, qx, qy, qdx, qdy, clearance, head_on_clearance, horizon):
    """Whether a robot at (x, y) on the path ``points`` comes, in its next ``horizon`` m,
    within ``clearance`` (m) of a robot at (qx, qy) driving in the unit direction
    (qdx, qdy) (zero: standing), driving another way than it there; if that way is head
    on, also within ``head_on_clearance`` of it in its next ``horizon + clearance -
    head_on_clearance`` m: the other stands on its line ahead, not beside its path. On a
    straight path, a robot less than ``head_on_clearance`` beside it is then in the way
    from the same distance on as under ``clearance`` alone."""
    near, ux, uy = path_ahead_near(x, y, points, qx, qy, horizon, clearance)
    way = ux * qdx + uy * qdy
    if not near or way >= _SAME_WAY:
        return False
    if way > _HEAD_ON:
        return True
    near, ux, uy = path_ahead_near(x, y, points, qx, qy, horizon + clearance - head_on_clearance,
                                   head_on_clearance)
    return near and ux * qdx + uy * qdy < _SAME_WAY
