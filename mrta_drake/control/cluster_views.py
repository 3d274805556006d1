"""Clusters as each robot sees them over a network: its own cluster in its view, and whether
the robots' views agree."""

import dataclasses
from collections.abc import Sequence

import numpy as np

from mrta_drake.payloads import Disturbances, Outage, frozen_array


def cluster_of(clusters: Sequence[tuple[int, ...]], robot: int) -> tuple[int, ...]:
    """The cluster of ``clusters`` (each led by its first member) that holds ``robot``."""
    return clusters[group_of(clusters, robot)]


def views_disagree(seen: Sequence[tuple[int, ...]]) -> bool:
    """Whether robots see a cluster differently: ``seen[i]`` is robot i's cluster as it sees
    it (leader first); some member j of it sees another leader or other members."""
    def key(cluster):
        return cluster[0], frozenset(cluster)
    return any(key(seen[j]) != key(cluster) for cluster in seen for j in cluster)


def group_of(groups: Sequence[tuple[int, ...]], robot: int) -> int:
    """The index of the group of ``groups`` that holds ``robot``."""
    return next(g for g, group in enumerate(groups) if robot in group)


def cut_off(disturbances: Disturbances, robot: int, time: float,
            view: np.ndarray) -> Disturbances:
    """``disturbances`` with ``robot`` also cut off from messages from ``time`` (s) on,
    knowing every robot as in ``view`` (N, 4): it plans alone, against ``view``, with the
    slow-down nominal (``Disturbances.seen_by``)."""
    if robot in disturbances.cut_off:
        return disturbances
    outage = Outage(robot, time, np.inf, frozen_array(view))
    return dataclasses.replace(disturbances, outages=disturbances.outages + (outage,))
