"""Robot clusters and their leaders.

A cluster is a connected component of the graph linking robots at most ``radius`` apart
(transitive closure: a chain of robots 3 m apart is one cluster). Each cluster is ordered by a
leader rule: active robots (those with somewhere to go) before inactive ones, robots that
stalled as leader after the others, then by the rule's key (smaller leads), then by scenario
priority, then by index. The first member is the leader.

A leader rule maps per-robot ``priorities`` (smaller leads, the scenario's order by default)
and ``distances_to_goal`` (m) to one sort key per robot; rules are plain functions so that a
user can plug in another one.
"""

from collections.abc import Callable

import numba
import numpy as np

from mrta_drake.stack.compiled_helper import compiled_helper

LeaderRule = Callable[[np.ndarray, np.ndarray], np.ndarray]


def by_priority(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """The scenario priority leads (smaller value first)."""
    return np.asarray(priorities, dtype=float)


def by_largest_priority(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """The largest scenario priority leads (the original MRTA-Sim stack's order)."""
    return -np.asarray(priorities, dtype=float)


def by_distance_to_goal(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """The robot nearest its goal leads (it clears the way soonest)."""
    return np.asarray(distances_to_goal, dtype=float)


LEADER_RULES: dict[str, LeaderRule] = {
    "priority": by_priority,
    "largest_priority": by_largest_priority,
    "distance_to_goal": by_distance_to_goal,
}


def register_leader_rule(name: str, rule: LeaderRule) -> None:
    """Make ``rule`` selectable by ``name`` in the controller's ``leader_rule`` parameter
    (in this process; for a sweep's worker processes, put the call in a module the sweep
    spec lists under ``plugins``)."""
    if not callable(rule):
        raise TypeError(f"leader rule {name!r} must be a function, got {rule!r}")
    LEADER_RULES[name] = rule


@compiled_helper
def cluster_labels(p, radius2, reachable):
    """The cluster number of each robot (positions p (N, 2), m): robots at most
    sqrt(``radius2``) apart, transitively, share one; robots not ``reachable`` (N bools;
    e.g. cut off from messages) are clusters of their own. Clusters are numbered in the
    order of their lowest index."""
    n = len(p)
    label = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    count = 0
    for seed in range(n):
        if label[seed] >= 0:
            continue
        label[seed], stack[0], top = count, seed, 1
        while top > 0:
            top -= 1
            i = stack[top]
            if not reachable[i]:
                continue
            for j in range(n):
                if (label[j] < 0 and reachable[j]
                        and (p[i, 0] - p[j, 0]) ** 2 + (p[i, 1] - p[j, 1]) ** 2 <= radius2):
                    label[j], stack[top] = count, j
                    top += 1
        count += 1
    return label


def form_clusters(positions, radius: float, priorities, distances_to_goal, active,
                  rule: LeaderRule = by_priority, stalled=None,
                  reachable=None) -> tuple[tuple[int, ...], ...]:
    """Clusters (lone robots included, as 1-tuples) in order of their lowest index, each
    ordered leader first (see the module docstring); ``stalled`` active robots (a leader
    that could not move) rank after the other active ones; robots not ``reachable`` (see
    ``cluster_labels``) are clusters of their own."""
    priorities = np.ascontiguousarray(priorities, dtype=float)
    n = len(priorities)
    keys = np.ascontiguousarray(rule(priorities, np.asarray(distances_to_goal, dtype=float)),
                                dtype=float)
    p = np.ascontiguousarray(positions, dtype=float).reshape(-1, 2)
    labels, order = _clusters_entry(
        p, float(radius) ** 2, np.ones(n, dtype=bool) if reachable is None
        else np.ascontiguousarray(reachable, dtype=bool), np.ascontiguousarray(active, dtype=bool),
        np.zeros(n, dtype=bool) if stalled is None
        else np.ascontiguousarray(stalled, dtype=bool), keys, priorities)
    return clusters_of(order, np.concatenate([[0], np.cumsum(np.bincount(labels))]))


def clusters_of(order, starts) -> tuple[tuple[int, ...], ...]:
    """The clusters ``order[starts[c]:starts[c + 1]]`` (``order`` (N,) robots sorted by
    cluster, as ``order_by_cluster`` sorts them; ``starts`` one more than there are
    clusters) as tuples of robot indices."""
    members, bounds = order.tolist(), starts.tolist()
    return tuple(tuple(members[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True))


@numba.njit(cache=True)
def _clusters_entry(p, radius2, reachable, active, stalled, keys, priorities):
    """``cluster_labels`` and ``order_by_cluster`` for Python, which cannot call a
    ``compiled_helper``."""
    labels = cluster_labels(p, radius2, reachable)
    return labels, order_by_cluster(labels, active, stalled, keys, priorities)


@compiled_helper
def order_by_cluster(labels, active, stalled, keys, priorities):
    """Robot indices sorted by cluster ``labels``, then leader first: ``active`` before
    inactive, not ``stalled`` before stalled, then by leader rule ``keys``, ``priorities``
    and index (insertion sort: clusters are small)."""
    order = np.arange(len(labels))
    for k in range(1, len(order)):
        i, j = order[k], k - 1
        while j >= 0 and _ranks_before(i, order[j], labels, active, stalled, keys, priorities):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = i
    return order


@compiled_helper
def _ranks_before(i, j, labels, active, stalled, keys, priorities):
    """Whether robot i comes strictly before robot j."""
    if labels[i] != labels[j]:
        return labels[i] < labels[j]
    if active[i] != active[j]:
        return active[i]
    if stalled[i] != stalled[j]:
        return stalled[j]
    if keys[i] != keys[j]:
        return keys[i] < keys[j]
    if priorities[i] != priorities[j]:
        return priorities[i] < priorities[j]
    return i < j


def stall_times_of(stall_times, speeds, members, starts, active, dt: float,
                   stall_time: float, stall_speed: float) -> np.ndarray:
    """Per robot, how long (s) it has stood as the active leader of one of the clusters
    ``members[starts[c]:starts[c + 1]]`` (leader first), after one more tick of ``dt`` s.
    A robot stands when it does not drive forward (``speeds`` below ``stall_speed``, m/s):
    a robot driving backwards is pushed back by the QP (its nominal never reverses), which
    is no progress. A robot that drives forward, is inactive or alone starts from 0; a
    demoted leader keeps its time, so others lead first; when every active member of a
    cluster has stalled (>= ``stall_time``), all start again. A cluster whose leader is
    blocked (e.g. by a follower that must move first) thus passes the lead on instead of
    waiting forever; the new leader driving on often pushes the one it took the lead from
    back out of its way, and that does not give the lead back."""
    new = np.empty(len(speeds))
    _stall_times(np.ascontiguousarray(stall_times, dtype=float),
                 np.ascontiguousarray(speeds, dtype=float), members, starts,
                 np.ascontiguousarray(active, dtype=bool), dt, stall_time, stall_speed, new)
    return new


@numba.njit(cache=True)
def _stall_times(stall_times, speeds, members, starts, active, dt, stall_time, stall_speed,
                 new):
    for i in range(len(speeds)):
        new[i] = stall_times[i] if speeds[i] < stall_speed and active[i] else 0.0
    for c in range(len(starts) - 1):
        cluster = members[starts[c]:starts[c + 1]]
        leader = cluster[0]
        if len(cluster) == 1:
            new[leader] = 0.0
            continue
        if active[leader] and speeds[leader] < stall_speed:
            new[leader] += dt
        candidates, stalled = 0, True
        for i in cluster:
            if active[i]:
                candidates += 1
                stalled = stalled and new[i] >= stall_time
        if candidates and stalled:
            for i in cluster:
                if active[i]:
                    new[i] = 0.0
