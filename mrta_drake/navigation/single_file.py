"""Which single-file segments a robot driving a route must hold, and where it must wait.

A single-file segment (``Roadways.segment_of``) is one lane driven both ways: two robots
meeting head-on in it could not pass. So a robot holds every segment of a *run* before it
enters the run and until it is out of it: a run is the route's edges in single-file
segments, with the stretches between them shorter than ``SingleFileParams.chain_gap``
(too short to wait on) counted in. The room queues grant a run's segments all at once
(``RoomQueues``), so a robot never holds part of a run while waiting for the rest.

Routes are polylines of points (world frame, m); edge ``j`` joins points ``j`` and
``j + 1``; a robot driving to point ``index`` is on edge ``index - 1``.
"""

import functools
import math
from dataclasses import dataclass

from mrta_drake.errors import InputError, require_positive
from mrta_drake.navigation.roadways import Roadways


@dataclass(frozen=True)
class SingleFileParams:
    """Distances along the route, m: ask for a run this far before its entry
    (``request_distance``), stop this far before it while not holding it
    (``hold_distance``), keep it until this far past its exit (``clear_distance``); stretches
    between segments shorter than ``chain_gap`` belong to the run."""

    request_distance: float = 4.0
    hold_distance: float = 1.5
    clear_distance: float = 1.0
    chain_gap: float = 5.0

    def __post_init__(self):
        require_positive(self, "request_distance", "hold_distance", "clear_distance",
                         "chain_gap", unit=" m")
        if self.hold_distance > self.request_distance:
            raise InputError(None, "request_distance", f"must be >= hold_distance "
                             f"({self.hold_distance} m), got {self.request_distance}")


@dataclass(frozen=True)
class Run:
    """Edges ``first`` .. ``last`` of a route (inclusive) and the segments they pass, each
    as (index, forward), in the order driven."""

    first: int
    last: int
    segments: tuple[tuple[int, bool], ...]


@functools.lru_cache(maxsize=512)
def route_runs(roadways: Roadways, route: tuple[tuple[float, float], ...],
               chain_gap: float) -> tuple[Run, ...]:
    """The runs of ``route`` in order (see the module docstring)."""
    runs: list[Run] = []
    gap = math.inf
    for j in range(len(route) - 1):
        segment = roadways.segment_of(route[j], route[j + 1])
        if segment is None:
            gap += math.dist(route[j], route[j + 1])
            continue
        if runs and gap < chain_gap:
            run = runs.pop()
            driven = {k for k, _ in run.segments}
            segments = run.segments if segment[0] in driven else (*run.segments, segment)
            runs.append(Run(run.first, j, segments))
        else:
            runs.append(Run(j, j, (segment,)))
        gap = 0.0
    return tuple(runs)


@dataclass(frozen=True)
class Need:
    """What a robot on a route needs now: ``segments`` to hold ((index, forward), sorted),
    and ``hold``: whether it must stand still until it holds them all."""

    segments: tuple[tuple[int, bool], ...] = ()
    hold: bool = False


NOTHING = Need()


def need(roadways: Roadways, route: tuple[tuple[float, float], ...], index: int, xy,
         params: SingleFileParams) -> Need:
    """The segments a robot at ``xy`` driving ``route`` to point ``index`` needs, and
    whether it must hold where it is until it has them (it is within ``hold_distance``
    of a run's entry, or in the run)."""
    if roadways.segment_count == 0 or len(route) < 2:
        return NOTHING
    wanted: dict[int, bool] = {}
    hold = False
    for run in route_runs(roadways, route, params.chain_gap):
        if index <= run.first:  # ahead: how far along the route to its entry?
            ahead = math.dist(xy, route[index]) + sum(
                math.dist(route[j], route[j + 1]) for j in range(index, run.first))
            if ahead > params.request_distance:
                break
            wanted.update(dict(run.segments))
            hold = hold or ahead <= params.hold_distance
        elif index <= run.last + 1:  # in it
            wanted.update(dict(run.segments))
            hold = True
        elif index == run.last + 2 and math.dist(xy, route[run.last + 1]) \
                < params.clear_distance:  # just out
            wanted.update(dict(run.segments))
    return Need(tuple(sorted(wanted.items())), hold) if wanted else NOTHING
