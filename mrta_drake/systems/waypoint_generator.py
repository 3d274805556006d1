"""Turns one robot's plan into waypoints: roadway legs, room queues, entries and service."""

import math
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.payloads import (
    ROBOT_STATE_SIZE,
    FleetPlan,
    QueueRequest,
    QueueState,
    RobotProgress,
    Stop,
    Visit,
    WaypointTarget,
)
from mrta_drake.roadways import Roadways

IDLE = "idle"  # no stop to do; the robot stands still
DRIVE = "drive"  # along a roadway leg to the tail slot of the stop's queue
QUEUE = "queue"  # requesting the stop's room, waiting at a queue slot
ENTER = "enter"  # holding the room, driving through the queue slots and entry to its point
SERVE = "serve"  # at the point: once holding the room, stand there for the service time
PARK = "park"  # no stop to do: wait on a free parking spot of the last location


@dataclass(frozen=True)
class WaypointParams:
    """Parameters of a ``WaypointGenerator``; distances in m, times in s."""

    waypoint_tolerance: float = 1.0  # a waypoint is reached within this distance
    reach_tolerance: float = 1.0  # a location's point is reached within this distance
    service_time: float = 1.0  # standing at the point, holding the room, to finish a stop
    request_distance: float = 3.0  # ask for a place in the queue this close to its tail slot
    release_distance: float = 5.0  # give a room back this far from its point
    parking_clearance: float = 0.8  # a parking spot is taken with another robot this close


@dataclass(frozen=True)
class _Drive:
    """The generator's whole state. ``index`` is the route waypoint being driven to (drive,
    enter) or the queue slot being waited at (queue); ``since`` the time service began;
    ``release`` the room the robot asks to release."""

    phase: str = IDLE
    stop: Stop | None = None
    route: tuple[tuple[float, float], ...] = ()
    index: int = 0
    since: float | None = None
    release: int | None = None
    visits: tuple[Visit, ...] = ()
    last_location: int | None = None

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the state can share it


def _point(xy) -> tuple[float, float]:
    return (float(xy[0]), float(xy[1]))


def _points(array) -> tuple[tuple[float, float], ...]:
    return tuple(_point(xy) for xy in np.asarray(array))


def _distance(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


class WaypointGenerator(LeafSystem):
    """Drives one robot through its plan's stops, one waypoint at a time.

    Inputs:
      ``plan``: abstract ``FleetPlan``; this robot's ``RobotPlan`` is the one named ``robot``.
      ``robot_state``: vector 4N, ``[x, y, theta, v]`` per robot; this robot's is at ``index``.
      ``queue_state``: abstract ``QueueState`` from ``RoomQueues``.
    Outputs (from the state; no direct feedthrough):
      ``target``: abstract ``WaypointTarget``, world frame, m.
      ``queue_request``: abstract ``QueueRequest``.
      ``progress``: abstract ``RobotProgress``; visit times are simulation times, s.

    ``rate_hz`` times a second an unrestricted update takes the current stop through these
    phases:

    - drive: follow ``roadways.leg`` from the last location (or, away from any location, a
      route from the nearest roadway node) to the tail slot of the stop's queue; waypoints
      count as reached within ``waypoint_tolerance``. Within ``request_distance`` of the
      tail slot, on the last segment, go to queue. A robot that still holds the stop's room
      (sent back to it) drives straight to the point instead.
    - queue: request the room and wait at slot ``min(place, slots - 1)``, moving up as the
      queue advances; robots beyond the last slot all wait at the tail slot.
    - enter: once holding the room, drive through the remaining slots and the entry path.
    - serve: within ``reach_tolerance`` of the point and holding the room, stand for
      ``service_time``; the stop is then done (a ``Visit`` at that time) and the next begins.
      A stop at the location the robot is already at starts here (requesting the room).

    The robot's stops are the plan's stops whose keys it has not completed, re-read every
    update: a new plan with the same first stop location changes nothing (only the stop);
    one with another location re-routes from the next roadway node ahead on the leg, from
    the exit node of the queue it waited in, or out of the room it entered. A completed stop
    is never redone. Without stops the robot parks: at a location with parking spots it
    drives to the first one no other robot is within ``parking_clearance`` of (park), off
    the point; elsewhere the target is inactive and it stands still.
    A parked robot given a stop starts it as if standing on the location's point.

    Release: the robot asks to release a room it holds (per ``queue_state``) once its
    current stop is elsewhere and it is more than ``release_distance`` from the room's
    point, or, with no stop left, once it is more than ``reach_tolerance`` from the point
    (at once where there is no parking spot). It keeps naming that room in ``release``
    until the queues no longer show it as the holder.
    """

    def __init__(
        self,
        robot: str,
        index: int,
        num_robots: int,
        roadways: Roadways,
        start_location: int | None = None,
        params: WaypointParams = WaypointParams(),
        rate_hz: float = 10.0,
    ):
        super().__init__()
        self._robot = robot
        self._index = index
        self._roadways = roadways
        self._params = params
        self._state_index = self.DeclareAbstractState(
            Value[object](_Drive(last_location=start_location))
        )
        self._plan = self.DeclareAbstractInputPort("plan", Value[object](FleetPlan(())))
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * num_robots)
        )
        self._queue_state = self.DeclareAbstractInputPort(
            "queue_state", Value[object](QueueState())
        )
        state_ticket = {self.abstract_state_ticket(self._state_index)}
        for name, payload, calc in (
            ("target", WaypointTarget(robot), self._calc_target),
            ("queue_request", QueueRequest(robot), self._calc_queue_request),
            ("progress", RobotProgress(robot, last_location=start_location), self._calc_progress),
        ):
            self.DeclareAbstractOutputPort(
                name,
                lambda payload=payload: Value[object](payload),
                calc,
                prerequisites_of_calc=state_ticket,
            )
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    # --- Outputs -----------------------------------------------------------------------------

    def _drive(self, context) -> _Drive:
        return context.get_abstract_state(self._state_index).get_value()

    def _calc_target(self, context, output):
        s = self._drive(context)
        if s.phase == PARK:
            parking = _point(self._roadways.place(s.last_location).parking[s.index])
            output.set_value(WaypointTarget(self._robot, True, parking, None, True))
            return
        if s.stop is None:
            output.set_value(WaypointTarget(self._robot))
            return
        place = self._roadways.place(s.stop.location)
        if s.phase in (DRIVE, ENTER):
            last = len(s.route) - 1
            current = s.route[s.index]
            after = s.route[s.index + 1] if s.index < last else None
            stop_here = s.index == last
        elif s.phase == QUEUE:
            current, after, stop_here = _point(place.queue[s.index]), None, True
        else:
            current, after, stop_here = _point(place.point), None, True
        output.set_value(WaypointTarget(self._robot, True, current, after, stop_here))

    def _calc_queue_request(self, context, output):
        s = self._drive(context)
        room = s.stop.location if s.phase in (QUEUE, ENTER, SERVE) else None
        output.set_value(QueueRequest(self._robot, room, s.release))

    def _calc_progress(self, context, output):
        s = self._drive(context)
        output.set_value(RobotProgress(self._robot, s.visits, s.last_location, s.stop))

    # --- Update ------------------------------------------------------------------------------

    def _update(self, context, state):
        s = self._drive(context)
        t = context.get_time()
        states = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        xy = _point(states[self._index])
        others = np.delete(states[:, :2], self._index, axis=0)
        queues = self._queue_state.Eval(context)
        done = {visit.key for visit in s.visits}
        remaining = [stop for stop in self._stops(context) if stop.key not in done]
        s = self._follow_plan(s, remaining[0] if remaining else None, xy, others)
        s = self._advance(s, xy, t, queues, remaining)
        s = replace(s, release=self._release(s, xy, queues))
        state.get_mutable_abstract_state(self._state_index).set_value(s)

    def _stops(self, context) -> tuple[Stop, ...]:
        plans = self._plan.Eval(context).plans
        if self._index < len(plans) and plans[self._index].robot == self._robot:
            return plans[self._index].stops
        return next((plan.stops for plan in plans if plan.robot == self._robot), ())

    def _follow_plan(self, s: _Drive, stop: Stop | None, xy, others) -> _Drive:
        if stop is None:
            if s.phase == PARK:
                return s
            place = None if s.last_location is None else self._roadways.place(s.last_location)
            if (place is None or not len(place.parking)
                    or _distance(xy, place.point) > self._params.reach_tolerance):
                return replace(s, phase=IDLE, stop=None, route=(), index=0, since=None)
            return replace(s, phase=PARK, stop=None, route=(), since=None,
                           index=self._free_parking(place, others))
        if s.stop is None:
            return self._start(s, stop, xy)
        if stop.location == s.stop.location:
            return replace(s, stop=stop)
        old = self._roadways.place(s.stop.location)
        if s.phase == DRIVE:
            route = self._splice(s.route[s.index:], old.exit_node, stop.location)
        elif s.phase == QUEUE:
            route = _points(self._roadways.route_from_node(old.exit_node, stop.location))
        else:
            route = _points(self._roadways.leg(old.id, stop.location))
        return replace(s, phase=DRIVE, stop=stop, route=route, index=0, since=None)

    def _free_parking(self, place, others: np.ndarray) -> int:
        """Index of the first of ``place``'s parking spots with no other robot near it (the
        last spot if all are taken)."""
        for k, spot in enumerate(place.parking):
            if not len(others) or np.min(np.linalg.norm(others - spot, axis=1)) > \
                    self._params.parking_clearance:
                return k
        return len(place.parking) - 1

    def _start(self, s: _Drive, stop: Stop, xy) -> _Drive:
        """Begin ``stop`` from standing (at the start, or after finishing a stop)."""
        roadways, tolerance = self._roadways, self._params.reach_tolerance
        parked = s.phase == PARK
        if (_distance(xy, roadways.place(stop.location).point) <= tolerance
                or (parked and s.last_location == stop.location)):
            return replace(s, phase=SERVE, stop=stop, route=(), index=0, since=None)
        last = s.last_location
        if last is None:  # e.g. a robot placed on a location's point without start_location
            last = next(
                (i for i in roadways.location_ids
                 if _distance(xy, roadways.place(i).point) <= tolerance),
                None,
            )
        if (
            last is not None
            and last != stop.location
            and (parked or _distance(xy, roadways.place(last).point) <= tolerance)
        ):
            route = roadways.leg(last, stop.location)
        else:
            route = roadways.route_from_point(xy, stop.location)
        return replace(s, phase=DRIVE, stop=stop, route=_points(route), index=0, since=None)

    def _splice(self, ahead, exit_node: str, location: int) -> tuple[tuple[float, float], ...]:
        """The rest of the route ``ahead`` up to its first roadway node that leads to
        ``location``, then the lanes from there; if none does (the robot is past the last
        node), the rest of the route and then the lanes from ``exit_node``."""
        for j, point in enumerate(ahead):
            node = self._roadways.node_at(point)
            route = None if node is None else self._roadways.route_from_node(node, location)
            if route is not None:
                return ahead[:j] + _points(route)
        return ahead + _points(self._roadways.route_from_node(exit_node, location))

    def _advance(self, s: _Drive, xy, t: float, queues: QueueState, remaining) -> _Drive:
        if s.stop is None:
            return s
        params = self._params
        place = self._roadways.place(s.stop.location)
        queue = queues.room(place.id)
        holding = queue is not None and queue.holder == self._robot
        if s.phase == DRIVE and holding:
            s = replace(s, phase=ENTER, route=(_point(place.point),), index=0)
        if s.phase == DRIVE:
            s = replace(s, index=self._reached(s, xy))
            if (
                s.index == len(s.route) - 1
                and _distance(xy, s.route[-1]) <= params.request_distance
            ):
                s = replace(s, phase=QUEUE, route=(), index=len(place.queue) - 1)
        if s.phase == QUEUE:
            if holding:
                route = _points(place.queue[s.index::-1]) + _points(place.entry)
                s = replace(s, phase=ENTER, route=route + (_point(place.point),), index=0)
            elif queue is not None and queue.slot_of(self._robot) is not None:
                s = replace(s, index=min(queue.slot_of(self._robot), len(place.queue) - 1))
        if s.phase == ENTER:
            s = replace(s, index=self._reached(s, xy))
            if s.index == len(s.route) - 1:
                s = replace(s, phase=SERVE, route=(), index=0)
        if s.phase == SERVE and holding and _distance(xy, place.point) <= params.reach_tolerance:
            since = t if s.since is None else s.since
            if t - since < params.service_time - 1e-9:
                return replace(s, since=since)
            stop = s.stop
            visit = Visit(stop.key, stop.location, t, stop.task, stop.action)
            s = replace(
                s, phase=IDLE, stop=None, since=None,
                visits=s.visits + (visit,), last_location=stop.location,
            )
            following = [other for other in remaining if other.key != stop.key]
            if following:
                s = self._start(s, following[0], xy)
        return s

    def _reached(self, s: _Drive, xy) -> int:
        """The first route index not yet reached, at most the last."""
        index = s.index
        while index < len(s.route) - 1 and (
            _distance(xy, s.route[index]) <= self._params.waypoint_tolerance
        ):
            index += 1
        return index

    def _release(self, s: _Drive, xy, queues: QueueState) -> int | None:
        for queue in queues.rooms:
            if queue.holder != self._robot:
                continue
            if s.stop is None:
                point = self._roadways.place(queue.room).point
                if s.phase != PARK or _distance(xy, point) > self._params.reach_tolerance:
                    return queue.room
                continue
            point = self._roadways.place(queue.room).point
            if (
                s.stop.location != queue.room
                and _distance(xy, point) > self._params.release_distance
            ):
                return queue.room
        return None
