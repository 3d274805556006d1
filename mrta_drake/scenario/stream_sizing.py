"""How many tasks a generated stream may hold so that a fleet can serve all of them in a run.

``size_stream`` sizes the ``tasks.generate`` block that ``mrta-sim import`` writes, from the
building's estimated travel times between its task locations (``Roadways.travel_time_estimate``,
s), the number of robots and the run's duration (s):

1. **Where**: a task's loaded leg must take at most a fifth of the run
   (``LEG_SHARE``), so that the leg to its pickup and a wait for the task before it fit
   too, and the last batch (2.) can still arrive after 0 s. The task locations used are
   the largest set whose legs both ways all fit (a building whose locations are far
   apart, e.g. a campus, uses a neighbourhood of them); with several levels, the set
   spanning the most levels first, so that tasks ride the lifts (a clinic whose levels are
   far apart through its lifts would otherwise keep its tasks on one level), and each
   level as likely as the next to hold a pickup or a drop-off;
   fewer than two: the run is too short for this building (``InputError``). The search
   looks at ``MAX_SETS`` sets that cannot grow at most (hundreds of locations many of
   whose pairs fit can make millions).
2. **When**: a task takes at most ``2 x longest leg + 2 x service time`` (to the pickup,
   then to the drop-off) among those locations, ``2 x mean leg + 2 x service time`` on
   average; the last batch arrives a longest and a mean task time before the end, time
   for a robot to finish the task in hand (on average) and then this one (at worst).
3. **How many**: batches (``BATCH_SIZE``, 1.5 tasks on average) come as many as keep the
   fleet busy ``UTILISATION`` (half) of the run but its last longest task time, leaving
   the rest for queues, lifts, single-file stretches and robots passing each other; at
   least one. They arrive evenly spaced from 0 s to the last arrival (no bursts beyond
   what the fleet was sized for).

The tasks themselves stay a seeded draw (``tasks.generate`` with the scenario's seed).
"""

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np

from mrta_drake.errors import InputError

LEG_SHARE = 0.2  # of the run: the longest loaded leg
UTILISATION = 0.5  # of the fleet's time spent on tasks
BATCH_SIZE = (1, 2)  # tasks per batch, uniform
MAX_SETS = 20_000  # sets of locations near each other looked at, at most (1.)


@dataclass(frozen=True)
class StreamSize:
    """A servable stream: batches arriving at ``times`` (s), before ``end`` (s), between
    the task locations ``locations`` (indices into the travel-time matrix), each drawn as
    a pickup or drop-off with its weight in ``weights`` (each level of the building alike:
    1 / the locations used on its level); ``names``: theirs, given by the caller when they
    are not all of them or not all alike."""

    times: tuple[float, ...]
    end: float
    locations: tuple[int, ...]
    weights: tuple[float, ...]
    names: tuple[str, ...] = ()


def size_stream(times: np.ndarray, robots: int, duration: float, service_time: float,
                source: str | None = None, levels: Sequence[str] | None = None
                ) -> StreamSize:
    """The stream for ``robots`` robots over ``duration`` s given the travel times
    ``times`` (n, n) s between task locations (module docstring); ``levels``: each
    location's level, when the building has several; ``source`` names the building in
    errors."""
    times = np.asarray(times, dtype=float)
    limit = LEG_SHARE * duration
    levels = levels or [""] * len(times)
    chosen = _largest_neighbourhood(times, limit, levels)
    if len(chosen) < 2:
        raise InputError(source, "--duration", f"{duration:g} s is too short for tasks in "
                         f"this building: no two task locations are within {limit:g} s of "
                         f"each other both ways (longest leg: {times.max():g} s)")
    legs = times[np.ix_(chosen, chosen)][~np.eye(len(chosen), dtype=bool)]
    longest_task = 2.0 * legs.max() + 2.0 * service_time
    mean_task = 2.0 * legs.mean() + 2.0 * service_time
    end = duration - longest_task - mean_task
    if end <= 0:
        raise InputError(source, "--duration", f"{duration:g} s is too short for tasks in "
                         f"this building: a task may take {longest_task:g} s, and the last "
                         f"needs that and a mean task ({mean_task:g} s) before the end")
    batches = max(1, math.floor(UTILISATION * robots * (duration - longest_task)
                                / (mean_task * 0.5 * sum(BATCH_SIZE))))
    times = tuple(float(math.floor(end * k / max(1, batches - 1))) for k in range(batches))
    used = [levels[i] for i in chosen]
    weights = tuple(round(1.0 / used.count(level), 6) for level in used)
    return StreamSize(times=times, end=float(end), locations=tuple(chosen), weights=weights)


def _largest_neighbourhood(times: np.ndarray, limit: float, levels: Sequence[str]
                           ) -> list[int]:
    """Of the sets of locations whose legs both ways take at most ``limit`` s, the one
    spanning the most ``levels`` (one per location), then the largest (ties: the one with
    the shortest legs, then the lowest indices); among the first ``MAX_SETS`` sets that
    cannot grow (``networkx.find_cliques``' order) where there are more."""
    n = len(times)
    near = nx.Graph()
    near.add_nodes_from(range(n))
    near.add_edges_from((i, j) for i in range(n) for j in range(i + 1, n)
                        if max(times[i, j], times[j, i]) <= limit)
    best: list[int] = []
    best_key = (0, 0, -math.inf)
    for clique in itertools.islice(nx.find_cliques(near), MAX_SETS):
        clique = sorted(clique)
        total = float(times[np.ix_(clique, clique)].sum())
        key = (len({levels[i] for i in clique}), len(clique), -total)
        if key > best_key or (key == best_key and clique < best):
            best, best_key = clique, key
    return best
