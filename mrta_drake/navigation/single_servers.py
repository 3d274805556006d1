"""How long a trip between two task locations keeps each single-server resource busy.

The building's single-server resources are its task locations (a room holds one robot at
a time: ``RoomQueues``) and its single-file segments (driven one way at a time:
``navigation.single_file``). A *trip* to location ``j`` is what a robot does for one stop
of a task: it leaves location ``i``'s point along ``Roadways.leg(i, j)``, moves up ``j``'s
queue from its tail slot to its head slot, drives ``j``'s entry path to the point and serves
there (``service_time``). It keeps busy, at ``speed`` (the speed robots drive):

- location ``j`` for the service and the drive from the head slot to the point and back
  out (twice the entry path's length);
- each single-file segment for as long as the robot holds it on the trip's route: a
  robot holds all the segments of a *run* (``single_file.route_runs``) from
  ``request_distance`` before its entry (or from the trip's start, if nearer) to
  ``clear_distance`` past its exit, or, where the run ends at the point, through the
  service; and for the service where the point stands in it (``single_file.stands_in``).

A trip from a location to itself (a robot already there) is the service alone. A *hold*
is the resources a trip keeps busy at once, one after the other along the trip (a run's
segments together, then the location), each resource as ``("location", id)`` or
``("segment", index)``; values in s.
"""

import math

from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import Run, SingleFileParams, route_runs, stands_in

PARAMS = SingleFileParams()  # the runs' own (``navigation.single_file``)


def trip_holds(roadways: Roadways, from_location: int, to_location: int, speed: float,
               service_time: float) -> dict[tuple[tuple[str, int], ...], float]:
    """The s each hold of the trip from ``from_location`` to serve at ``to_location``
    (ids) driven at ``speed`` m/s lasts, keyed by the resources it holds at once (module
    docstring): the location alone, a run's segments together, a segment the point
    stands in alone for the service where no run ending there holds it."""
    place = roadways.place(to_location)
    inside = place.doorway
    holds = {(("location", to_location),):
             2.0 * roadways.route_length(inside) / speed + service_time}
    standing = set(stands_in(roadways, place.point, PARAMS))
    if from_location != to_location:
        route = tuple(map(tuple, (*roadways.leg(from_location, to_location),
                                  *place.queue[-2::-1], *inside[1:])))
        for run in route_runs(roadways, route, PARAMS.chain_gap, PARAMS.stand_distance):
            serving = run.last == len(route) - 2  # held through the service
            key = tuple(sorted(("segment", k) for k, _ in run.segments))
            holds[key] = (holds.get(key, 0.0) + _run_held(route, run) / speed
                          + (service_time if serving else 0.0))
            if serving:
                standing -= {k for k, _ in run.segments}
    for k in sorted(standing):
        holds[("segment", k),] = holds.get((("segment", k),), 0.0) + service_time
    return holds


def _run_held(route, run: Run) -> float:
    """The m a robot driving ``route`` holds ``run``'s segments for: from where it asks
    for them, ``request_distance`` before the run's entry (or the route's start, if
    nearer), to ``clear_distance`` past its exit (to the route's end where the run ends
    there)."""
    hops = [math.dist(a, b) for a, b in zip(route[:-1], route[1:], strict=True)]
    before = min(PARAMS.request_distance, sum(hops[:run.first]))
    past = 0.0 if run.last == len(route) - 2 else PARAMS.clear_distance
    return before + sum(hops[run.first:run.last + 1]) + past
