"""Which single-file segments a robot driving a route must hold, and where it must wait.

A single-file segment (``Roadways.segment_of``) is one lane driven both ways: two robots
meeting head-on in it could not pass. So a robot holds every segment of a *run* before it
enters the run and until it is out of it: a run is the route's edges in single-file
segments, with the stretches between them shorter than ``SingleFileParams.chain_gap``
(too short to wait on) counted in, and the segments where the route ends, in which the
robot will stand. The room queues grant a run's segments all at once
(``RoomQueues``), so a robot never holds part of a run while waiting for the rest. A hop
that leaves the lanes (from a queue slot or parking spot beside them) onto a segment's lane
enters that segment like a lane of it.

A robot standing in a segment (within ``stand_distance`` of one of its lanes: queueing,
serving at a point on it) keeps holding it (``standing``), so that the segment is never
granted to a robot that would drive into it; a segment where robots stop (a location's
point or queue slot on it, ``stop_segments``) is held by one robot at a time, since a robot
following another into it could not pass it where it stops.

Routes are polylines of points (world frame, m); edge ``j`` joins points ``j`` and
``j + 1``; a robot driving to point ``index`` is on edge ``index - 1``.
"""

import functools
import math
from dataclasses import dataclass

import numpy as np

from mrta_drake.errors import InputError, require_positive
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.world.segment_distances import segment_distances


@dataclass(frozen=True)
class SingleFileParams:
    """Distances along the route, m: ask for a run this far before its entry
    (``request_distance``), stop this far before it while not holding it
    (``hold_distance``), keep it until this far past its exit (``clear_distance``); stretches
    between segments shorter than ``chain_gap`` belong to the run. A robot whose centre is
    within ``stand_distance`` of a segment's lane stands in it (0.5 m: two 0.22 m robots
    with a few centimetres between them)."""

    request_distance: float = 4.0
    hold_distance: float = 1.5
    clear_distance: float = 1.0
    chain_gap: float = 5.0
    stand_distance: float = 0.5

    def __post_init__(self):
        require_positive(self, "request_distance", "hold_distance", "clear_distance",
                         "chain_gap", "stand_distance", unit=" m")
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


_BESIDE = 2.5  # m: the farthest a queue slot stands beside its lane (2.2 m, rmf_navigation)


def hop_segment(roadways: Roadways, a, b, c) -> tuple[int, bool] | None:
    """The segment the hop from route point ``a`` to ``b`` drives (``c``: the point after
    ``b``, or None): its lane's; for a hop from a roadway node to a spot beside a lane
    from it (a queue slot beside the lanes, within ``_BESIDE``), that lane's; for a hop
    from off the lanes (``a`` no roadway node) onto a segment's lane at ``b``, that
    segment (the way the route goes on along it)."""
    segment = roadways.segment_of(a, b)
    if segment is not None:
        return segment
    start = roadways.node_at(a)
    if start is not None:
        if roadways.node_at(b) is not None:
            return None
        lanes = [(_to_lane(b, a, roadways.node_position(n)), n)
                 for n in roadways.graph.successors(start)]
        gap, n = min(lanes, key=lambda lane: lane[0], default=(math.inf, None))
        return roadways.segment_of(a, roadways.node_position(n)) if gap <= _BESIDE else None
    if c is not None and (onward := roadways.segment_of(b, c)) is not None:
        return onward
    near = _near(roadways, b, 1e-3)
    return (near[0], True) if near else None


def _to_lane(xy, a, b) -> float:
    """Distance (m) from ``xy`` to the lane from ``a`` to ``b`` where ``xy`` lies beside
    it (its foot on the lane, past ``a``), else infinity."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = ((xy[0] - a[0]) * dx + (xy[1] - a[1]) * dy) / max(dx * dx + dy * dy, 1e-18)
    if not 0.0 < t <= 1.0:
        return math.inf
    return math.hypot(xy[0] - a[0] - t * dx, xy[1] - a[1] - t * dy)


@functools.lru_cache(maxsize=512)
def route_runs(roadways: Roadways, route: tuple[tuple[float, float], ...],
               chain_gap: float, stand_distance: float = 0.0) -> tuple[Run, ...]:
    """The runs of ``route`` in order (see the module docstring). The segments within
    ``stand_distance`` of the route's end, where the robot will stand (a point where two
    segments meet, a slot by a lane), belong to the run that ends there (else to a run of
    the last edge): it asks for them before it drives in, not once it stands in the way."""
    runs: list[Run] = []
    gap = math.inf
    for j in range(len(route) - 1):
        segment = hop_segment(roadways, route[j], route[j + 1],
                               route[j + 2] if j + 2 < len(route) else None)
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
    last = len(route) - 2
    if stand_distance > 0.0 and last >= 0:
        ending = runs[-1] if runs and runs[-1].last == last else Run(last, last, ())
        driven = {k for k, _ in ending.segments}
        extra = tuple((k, True) for k in _near(roadways, route[-1], stand_distance)
                      if k not in driven)
        if extra:
            if runs and runs[-1] is ending:
                runs.pop()
            runs.append(Run(ending.first, last, ending.segments + extra))
    return tuple(runs)


@dataclass(frozen=True)
class Need:
    """What a robot on a route needs now: ``segments`` to hold ((index, forward), sorted),
    ``hold``: whether it must stand still until it holds them all, and ``stops``: those of
    them it will stand in (sorted indices: its route ends there, or it stands), which it
    holds alone where robots stop (``stop_segments``); it only drives through the others;
    ``standing``: those it stands in now (sorted indices)."""

    segments: tuple[tuple[int, bool], ...] = ()
    hold: bool = False
    stops: tuple[int, ...] = ()
    standing: tuple[int, ...] = ()

    def without(self, dropped) -> "Need":
        """The same need, holding back, less the segments ``dropped`` (indices)."""
        return Need(tuple(seg for seg in self.segments if seg[0] not in dropped), True,
                    tuple(k for k in self.stops if k not in dropped),
                    tuple(k for k in self.standing if k not in dropped))


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
    stops: tuple[int, ...] = ()
    for run in route_runs(roadways, route, params.chain_gap, params.stand_distance):
        if run.last == len(route) - 2:  # the run where the route ends: it stands there
            stops = stands_in(roadways, route[-1], params)
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
    if not wanted:
        return NOTHING
    return Need(tuple(sorted(wanted.items())), hold, tuple(k for k in stops if k in wanted))


@functools.lru_cache(maxsize=64)
def _segment_lanes(roadways: Roadways) -> tuple[tuple[int, tuple[float, float],
                                                      tuple[float, float]], ...]:
    """Every lane of a single-file segment: (segment index, start, end), m."""
    lanes = []
    for a, b in roadways.graph.edges:
        start, end = roadways.node_position(a), roadways.node_position(b)
        segment = roadways.segment_of(start, end)
        if segment is not None:
            lanes.append((segment[0], (float(start[0]), float(start[1])),
                          (float(end[0]), float(end[1]))))
    return tuple(lanes)


def segment_lanes(roadways: Roadways, segment: int
                  ) -> tuple[tuple[tuple[float, float], tuple[float, float]], ...]:
    """The lanes (start, end; world frame, m) of single-file segment ``segment``."""
    return tuple((a, b) for k, a, b in _segment_lanes(roadways) if k == segment)


def _near(roadways: Roadways, xy, distance: float) -> tuple[int, ...]:
    """The segments (sorted indices) with a lane within ``distance`` (m) of point ``xy``."""
    return _near_point(roadways, float(xy[0]), float(xy[1]), distance)


@functools.lru_cache(maxsize=64)
def _lane_pieces(roadways: Roadways) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_segment_lanes`` as arrays: each lane's segment index (L,), start and end (L, 2)."""
    lanes = _segment_lanes(roadways)
    return (np.array([k for k, _, _ in lanes], dtype=int),
            np.array([a for _, a, _ in lanes], dtype=float).reshape(-1, 2),
            np.array([b for _, _, b in lanes], dtype=float).reshape(-1, 2))


@functools.lru_cache(maxsize=4096)
def _near_point(roadways: Roadways, x: float, y: float, distance: float
                ) -> tuple[int, ...]:
    """``_near`` of the point (``x``, ``y``), kept per point: robots standing still (idle,
    queueing) ask for the same point at every update."""
    segments, starts, ends = _lane_pieces(roadways)
    near = segment_distances((x, y), starts, ends) <= distance
    return tuple(sorted({int(k) for k in segments[near]}))


def stands_in(roadways: Roadways, xy, params: SingleFileParams) -> tuple[int, ...]:
    """The segments (sorted indices) a robot at ``xy`` stands in: within
    ``stand_distance`` of one of their lanes."""
    return _near(roadways, xy, params.stand_distance) if roadways.segment_count else ()


def standing(roadways: Roadways, xy, spot, held, params: SingleFileParams) -> Need:
    """What a robot at ``xy`` standing at, or moving up to, ``spot`` (a queue slot, a
    location's point) needs: the segments within ``stand_distance`` of either, each the
    way it holds it already (``held``: index -> forward) or forward; it holds back until it
    holds those at ``spot`` unless it stands in them already."""
    if roadways.segment_count == 0:
        return NOTHING
    here = stands_in(roadways, xy, params)
    there = _near(roadways, spot, params.stand_distance)
    wanted = sorted(set(here) | set(there))
    if not wanted:
        return NOTHING
    return Need(tuple((k, held.get(k, True)) for k in wanted),
                hold=not set(there) <= set(held) | set(here), stops=tuple(wanted),
                standing=tuple(sorted(here)))


@functools.lru_cache(maxsize=64)
def stop_segments(roadways: Roadways, params: SingleFileParams) -> frozenset[int]:
    """The segments robots stop in: those within ``stand_distance`` of a location's point
    or queue slot (one robot at a time holds each, see the module docstring)."""
    stops = set()
    for i in roadways.location_ids:
        place = roadways.place(i)
        for xy in (place.point, *place.queue):
            stops.update(_near(roadways, xy, params.stand_distance))
    return frozenset(stops)
