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

import numpy as np

LeaderRule = Callable[[np.ndarray, np.ndarray], np.ndarray]


def by_priority(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """The scenario priority leads (smaller value first)."""
    return np.asarray(priorities, dtype=float)


def by_distance_to_goal(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """The robot nearest its goal leads (it clears the way soonest)."""
    return np.asarray(distances_to_goal, dtype=float)


LEADER_RULES: dict[str, LeaderRule] = {
    "priority": by_priority,
    "distance_to_goal": by_distance_to_goal,
}


def connected_groups(positions, radius: float) -> list[list[int]]:
    """Indices of robots (positions (N, 2), m) grouped by transitive closure of being at most
    ``radius`` apart; groups and members in ascending index order."""
    p = np.asarray(positions, dtype=float).reshape(-1, 2)
    n = len(p)
    d2 = np.sum((p[:, None, :] - p[None, :, :]) ** 2, axis=-1)
    linked = d2 <= radius * radius
    label = np.full(n, -1)
    groups = []
    for seed in range(n):
        if label[seed] >= 0:
            continue
        label[seed] = len(groups)
        frontier, members = [seed], [seed]
        while frontier:
            new = np.flatnonzero(linked[frontier].any(axis=0) & (label < 0))
            label[new] = len(groups)
            frontier = new.tolist()
            members.extend(frontier)
        groups.append(sorted(members))
    return groups


def form_clusters(positions, radius: float, priorities, distances_to_goal, active,
                  rule: LeaderRule = by_priority, stalled=None) -> tuple[tuple[int, ...], ...]:
    """Clusters (lone robots included, as 1-tuples) in order of their lowest index, each
    ordered leader first (see the module docstring); ``stalled`` active robots (a leader
    that could not move) rank after the other active ones."""
    priorities = np.asarray(priorities, dtype=float)
    keys = np.asarray(rule(priorities, np.asarray(distances_to_goal, dtype=float)), dtype=float)
    stalled = np.zeros(len(priorities), dtype=bool) if stalled is None else stalled
    clusters = []
    for members in connected_groups(positions, radius):
        clusters.append(tuple(sorted(members, key=lambda i: (
            not active[i], bool(stalled[i]), keys[i], priorities[i], i))))
    return tuple(clusters)


def leader_stall_times(stall_times, speeds, clusters, active, dt: float, stall_time: float,
                       stall_speed: float) -> np.ndarray:
    """Per robot, how long (s) it has stood (|speed| < ``stall_speed``, m/s) as the active
    leader of a cluster, after one more tick of ``dt`` s. A robot that moves, is inactive or
    alone starts from 0; a demoted leader keeps its time, so others lead first; when every
    active member of a cluster has stalled (>= ``stall_time``), all start again. A cluster
    whose leader is blocked (e.g. by a follower that must move first) thus passes the lead on
    instead of waiting forever."""
    new = np.where((np.abs(speeds) < stall_speed) & np.asarray(active, dtype=bool),
                   np.asarray(stall_times, dtype=float), 0.0)
    for cluster in clusters:
        if len(cluster) == 1:
            new[cluster[0]] = 0.0
            continue
        if active[cluster[0]] and np.abs(speeds[cluster[0]]) < stall_speed:
            new[cluster[0]] += dt
        candidates = [i for i in cluster if active[i]]
        if candidates and all(new[i] >= stall_time for i in candidates):
            new[candidates] = 0.0
    return new
