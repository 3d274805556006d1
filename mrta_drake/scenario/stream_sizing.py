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
   for a robot to finish the task in hand (on average) and then this one (at worst); with
   ``holds`` (3.), earlier by those two tasks' expected waits for single servers.
3. **How many**: batches (``BATCH_SIZE``, 1.5 tasks on average) come as many as keep the
   fleet busy ``UTILISATION`` (half) of the run but its last longest task time, leaving
   the rest for queues, lifts, single-file stretches and robots passing each other, and
   as the whole fleet can serve in that time with the waits for the single-server
   resources (``holds``: rooms, single-file segments) included. A task is its loaded
   trip from the pickup to the drop-off and an empty trip to the pickup from wherever the
   nearest of the free robots (``1 - UTILISATION`` of them, each at a drop-off drawn with
   the drop-off weights) stands; a batch of two tasks that share pickup and drop-off is
   carried on one trip (robots carry two items). A trip holds the resources it needs in
   turn (a run of segments together, then the room), and waits for each hold as long as
   for the busiest of its resources: with tasks arriving at ``rate`` (the batches' tasks
   over the run but its longest task) and a resource held ``L`` s and ``S2`` s^2 per
   task (its holds' lengths and their squares, summed over the expected trips), the
   Pollaczek-Khinchine mean wait of a single server with random arrivals, ``rate x S2 /
   (2 (1 - rate x L))`` s. The batches are the most, up to the fleet's, whose tasks'
   mean time and expected waits fit ``robots x (run - longest task)``. At least one
   batch. They arrive evenly spaced from 0 s to the last arrival (no bursts beyond what
   the fleet was sized for).

The tasks themselves stay a seeded draw (``tasks.generate`` with the scenario's seed).
"""

import itertools
import math
from collections import Counter
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np

from mrta_drake.errors import InputError

LEG_SHARE = 0.2  # of the run: the longest loaded leg
UTILISATION = 0.5  # of the fleet's time spent on tasks
BATCH_SIZE = (1, 2)  # tasks per batch, uniform
MEAN_BATCH = 0.5 * sum(BATCH_SIZE)  # tasks per batch on average
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


Holds = Callable[[int, int], Mapping[tuple[Hashable, ...], float]]
TripHolds = list[tuple[float, Mapping[tuple[Hashable, ...], float]]]


def size_stream(times: np.ndarray, robots: int, duration: float, service_time: float,
                source: str | None = None, levels: Sequence[str] | None = None,
                holds: Holds | None = None) -> StreamSize:
    """The stream for ``robots`` robots over ``duration`` s given the travel times
    ``times`` (n, n) s between task locations (module docstring); ``levels``: each
    location's level, when the building has several; ``holds(i, j)``: the s a robot's trip
    from location ``i`` to serve at ``j`` (indices into ``times``; ``i == j``: serving
    only) holds single-server resources (any keys), by the resources held at once,
    without: the fleet bound alone; ``source`` names the building in errors."""
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
    used = [levels[i] for i in chosen]
    weights = tuple(round(1.0 / used.count(level), 6) for level in used)
    span = duration - longest_task
    batches = math.floor(UTILISATION * robots * span / (mean_task * MEAN_BATCH))
    if holds is not None:
        trips = _trip_holds(holds, chosen, _trips(times[np.ix_(chosen, chosen)], weights,
                                                  (1.0 - UTILISATION) * robots))
        batches = _with_waits(trips, batches, mean_task, robots, span)
        end = max(0.0, end - 2.0 * _wait(trips, max(1, batches) * MEAN_BATCH / span))
    batches = max(1, batches)
    times = tuple(float(math.floor(end * k / max(1, batches - 1))) for k in range(batches))
    return StreamSize(times=times, end=float(end), locations=tuple(chosen), weights=weights)


def _trips(times: np.ndarray, weights: Sequence[float], free: float) -> np.ndarray:
    """The expected trips per task (from, to) between locations with the travel times
    ``times`` (s) and ``weights`` (``size_stream``, rule 3): the loaded trip from the
    pickup to the drop-off, and the empty trip to the pickup from the nearest of ``free``
    robots, each standing at a drop-off; tasks carried together count one trip for two."""
    p = np.asarray(weights, dtype=float) / sum(weights)
    task = p[:, None] * p[None, :] / (1.0 - p[:, None])  # (pickup, drop-off)
    np.fill_diagonal(task, 0.0)
    nearest = _nearest_of(times, task.sum(axis=0), free)  # (from, pickup)
    return _carried_alone(task) * (task + nearest * p[None, :])


def _nearest_of(times: np.ndarray, spread: np.ndarray, robots: float) -> np.ndarray:
    """(from, to): the chance that, of ``robots`` robots standing at locations drawn with
    the chances ``spread``, the one nearest to ``to`` (``times`` (from, to), s; ties: the
    lower index) stands at ``from``: ``(1 - F(before from))^robots - (1 - F(from))^robots``
    with ``F`` the chance of a location no farther than it, in that order."""
    chance = np.zeros_like(times, dtype=float)
    for to in range(len(times)):
        order = np.lexsort((np.arange(len(times)), times[:, to]))
        within = np.cumsum(spread[order])
        chance[order, to] = -np.diff((1.0 - within) ** robots, prepend=1.0)
    return chance


def _carried_alone(task: np.ndarray) -> float:
    """The trips per task where robots carry two tasks (``capacity``) that share pickup
    and drop-off together: a batch of two (``BATCH_SIZE``) does so with the chance that
    its tasks share them, ``sum(task^2)``, and one trip then serves both."""
    paired = np.mean([n == 2 for n in range(BATCH_SIZE[0], BATCH_SIZE[1] + 1)])
    in_pairs = 2.0 * paired / MEAN_BATCH  # of tasks, in batches of two
    return 1.0 - 0.5 * in_pairs * float((task ** 2).sum())


def _trip_holds(holds: Holds, chosen: Sequence[int], trips: np.ndarray) -> TripHolds:
    """Each trip's expected count per task (``_trips``, between ``chosen`` locations) and
    its holds (``size_stream``), the trips that happen."""
    return [(float(trips[a, b]), holds(chosen[a], chosen[b]))
            for a, b in zip(*np.nonzero(trips), strict=True)]


def _with_waits(trips: TripHolds, batches: int, mean_task: float, robots: int,
                span: float) -> int:
    """The most batches, up to ``batches``, whose tasks' mean time ``mean_task`` (s) and
    expected waits for the holds of their ``trips`` (``_wait``) fit ``robots`` robots'
    time over ``span`` s (module docstring, rule 3)."""
    while batches > 1 and batches * MEAN_BATCH * (
            mean_task + _wait(trips, batches * MEAN_BATCH / span)) > robots * span:
        batches -= 1
    return batches


def _wait(trips: TripHolds, rate: float) -> float:
    """The expected s a task waits for the resources its trips hold, at ``rate`` tasks
    per s (module docstring, rule 3): per hold, the longest wait among its resources;
    infinite where a resource is busy all the time."""
    load: Counter = Counter()  # s per task
    square: Counter = Counter()  # s^2 per task
    for count, held in trips:
        for resources, seconds in held.items():
            for resource in resources:
                load[resource] += count * seconds
                square[resource] += count * seconds ** 2
    if rate * max(load.values(), default=0.0) >= 1.0:
        return math.inf
    wait = {r: rate * square[r] / (2.0 * (1.0 - rate * load[r])) for r in load}
    return sum(count * sum(max(wait[r] for r in resources) for resources in held)
               for count, held in trips)


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
