"""The lifts of a building as shared resources: cabins carrying as many robots as fit, each
robot sent to the lift of its bank with the shortest expected wait, and the ride that moves
the riders to the cabin on the other level."""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.errors import require_non_negative, require_positive
from mrta_drake.payloads import (
    ROBOT_STATE_SIZE,
    LiftRequest,
    LiftState,
    LiftStatus,
    Relocations,
)


@dataclass(frozen=True)
class LiftParams:
    """How the lifts move and are shared. ``speed`` (m/s) and ``acceleration`` (m/s^2) are
    Open-RMF's Gazebo lift defaults; ``door_time`` (s) is the doors closing before and
    opening after a ride, half each; a rider within ``board_tolerance`` m of its berth is
    aboard; once one is, the doors wait at most ``board_wait`` s for the other riders (those
    not aboard then wait for the next trip, first in the queue); a rider farther than
    ``leave_distance`` m from the cabin's point has left it.
    Riders stand ``berth_clearance`` m apart (and from the cabin's walls); lifts whose cabins
    on a level lie within ``bank_distance`` m of each other form a bank, and a robot asking
    for one of them is sent to the one with the shortest expected wait, counting the drive
    to it at ``approach_speed`` m/s."""

    speed: float = 2.0
    acceleration: float = 1.2
    door_time: float = 4.0
    board_tolerance: float = 0.5
    leave_distance: float = 2.0
    board_wait: float = 20.0
    berth_clearance: float = 0.5
    bank_distance: float = 15.0
    approach_speed: float = 0.5

    def __post_init__(self):
        require_positive(self, "speed", "acceleration", "board_tolerance", "leave_distance",
                         "approach_speed", "board_wait")
        require_non_negative(self, "door_time", unit=" s")
        require_non_negative(self, "berth_clearance", "bank_distance", unit=" m")


@dataclass(frozen=True)
class LiftStop:
    """Where a lift stops: on ``level`` (at ``elevation`` m) its cabin's roadway ``node`` is
    at ``cabin`` (x, y); the cabin's centre is at ``centre`` and the door that opens on this
    level at ``door`` (both default to ``cabin``); world frame, m."""

    level: str
    cabin: tuple[float, float]
    elevation: float
    node: str
    centre: tuple[float, float] | None = None
    door: tuple[float, float] | None = None

    @property
    def middle(self) -> tuple[float, float]:
        return self.cabin if self.centre is None else self.centre


@dataclass(frozen=True)
class LiftSpec:
    """A lift ``name`` with its ``stops`` in level order, the cabin first at
    ``initial_level``; the cabin is ``width`` x ``depth`` m, turned by ``yaw`` rad (a
    cabin of size 0 holds one robot, at the cabin's point)."""

    name: str
    stops: tuple[LiftStop, ...]
    initial_level: str
    width: float = 0.0
    depth: float = 0.0
    yaw: float = 0.0

    def stop(self, level: str) -> LiftStop:
        return next(stop for stop in self.stops if stop.level == level)

    def serves(self, from_level: str, to_level: str) -> bool:
        levels = {stop.level for stop in self.stops}
        return from_level in levels and to_level in levels


def ride_time(params: LiftParams, from_elevation: float, to_elevation: float) -> float:
    """Seconds from the doors closing at ``from_elevation`` to their opening at
    ``to_elevation`` (m): ``door_time`` plus a trapezoidal (or, short, triangular) speed
    profile."""
    distance = abs(to_elevation - from_elevation)
    v, a = params.speed, params.acceleration
    if distance >= v * v / a:
        moving = distance / v + v / a
    else:
        moving = 2.0 * math.sqrt(distance / a)
    return params.door_time + moving


def expected_ride_time(params: LiftParams, from_elevation: float, to_elevation: float
                       ) -> float:
    """Seconds a robot expects to spend on a ride between the elevations (m), from asking
    to the doors opening at the other level: the ride, boarding (``door_time``) and, the
    cabin being at the other level half the time, half a ride for calling it."""
    ride = ride_time(params, from_elevation, to_elevation)
    return 1.5 * ride + params.door_time


def cabin_berths(lift: LiftSpec, level: str, robot_radius: float, clearance: float
                 ) -> tuple[tuple[float, float], ...]:
    """Where riders of radius ``robot_radius`` m stand in ``lift``'s cabin on ``level``
    (world frame, m): a grid ``2 robot_radius + clearance`` m apart and ``clearance`` m
    clear of the walls, boarding order farthest from the door first; the cabin's point
    alone if not even one fits beside another."""
    stop = lift.stop(level)
    pitch = 2.0 * robot_radius + clearance
    counts = [int(math.floor((side - 2.0 * (clearance + robot_radius)) / pitch)) + 1
              if side >= 2.0 * (clearance + robot_radius) else 0
              for side in (lift.width, lift.depth)]
    if counts[0] * counts[1] < 2:
        return (stop.cabin,)
    c, s = math.cos(lift.yaw), math.sin(lift.yaw)
    centre = stop.middle
    berths = []
    for i in range(counts[0]):
        for j in range(counts[1]):
            u, v = (i - 0.5 * (counts[0] - 1)) * pitch, (j - 0.5 * (counts[1] - 1)) * pitch
            berths.append((centre[0] + c * u - s * v, centre[1] + s * u + c * v))
    door = stop.cabin if stop.door is None else stop.door
    return tuple(sorted(berths, key=lambda p: (-round(math.dist(p, door), 6), p)))


@dataclass(frozen=True)
class LiftEvent:
    """At ``time`` s, ``robot`` did ``kind`` (request, board, depart, arrive, leave) with
    ``lift`` at ``level``."""

    time: float
    lift: str
    robot: str
    kind: str
    level: str


@dataclass(frozen=True)
class _Cabin:
    """One lift's state: see ``LiftStatus``; ``berths`` each rider's berth index,
    ``boarded`` the riders aboard; ``origin`` and ``destination`` the trip's levels;
    ``since`` and ``until`` when the current call or ride phase began and ends (s); while the
    doors are open, ``since`` is when the first rider boarded."""

    level: str
    riders: tuple[str, ...] = ()
    berths: tuple[int, ...] = ()
    boarded: tuple[str, ...] = ()
    waiting: tuple[str, ...] = ()
    phase: str = "idle"
    origin: str = ""
    destination: str = ""
    since: float = 0.0
    until: float = 0.0

    def trip(self) -> tuple[str, str, float, float] | None:
        """While the cabin moves: (from level, to level, start s, end s)."""
        if self.phase == "called":
            return (self.level, self.origin, self.since, self.until)
        if self.phase == "travel":
            return (self.origin, self.destination, self.since, self.until)
        return None


def _berths_level(c: _Cabin) -> str:
    """The level whose berths the riders of ``c`` stand at (or drive to): the trip's
    destination once there, else its origin."""
    return c.destination if c.phase == "out" else (c.origin or c.level)


@dataclass(frozen=True)
class _Bank:
    cabins: tuple[_Cabin, ...]
    moves: tuple[tuple[int, tuple[float, float, float]] | None, ...]
    events: tuple[LiftEvent, ...] = ()

    def __deepcopy__(self, memo):
        return self  # immutable


class LiftBank(LeafSystem):
    """The building's lifts (``lifts``), each a cabin carrying as many robots as fit.

    .. pydrake_system::

        name: LiftBank
        input_ports:
        - request_<robot>
        - robot_state
        output_ports:
        - lift_state
        - relocations
        - events

    Inputs: ``request_<robot>``: abstract ``LiftRequest``; ``robot_state``: vector 4N,
    ``[x, y, theta, v]`` per robot, world frame, m, rad, m/s.
    Outputs (from the state): ``lift_state``: abstract ``LiftState``; ``relocations``:
    abstract ``Relocations`` for the robots block; ``events``: a tuple of ``LiftEvent``.

    Each cabin has berths for robots of ``robot_radius`` m (``cabin_berths``). ``rate_hz``
    times a second an unrestricted update: a robot newly asking for a lift joins the queue
    of the lift of that lift's bank (lifts serving both levels with cabins within
    ``bank_distance``) with the shortest expected wait (a ``request`` event); robots no
    longer asking leave their queue. Per lift: a free cabin takes the first waiting robot's
    trip (first empty to its level if elsewhere, taking ``ride_time``) and, while its doors
    are open, every waiting robot with the same trip, up to its berths; each rider drives
    to its berth (within ``board_tolerance``: ``board``); once all are aboard (or
    ``board_wait`` after the first, the others back to the head of the queue) the doors
    close (half of ``door_time``: ``depart``) and at the end of the ride (``arrive``) the
    riders are relocated by the offset between the two cabins, headings kept; each rider
    ``leave``s once ``leave_distance`` from both cabins' points, and the cabin is free when
    all have. A rider that stops asking before boarding gives its berth up.
    """

    def __init__(self, robot_names: Sequence[str], lifts: Sequence[LiftSpec],
                 params: LiftParams = LiftParams(), *, rate_hz: float,
                 robot_radius: float = 0.22):
        super().__init__()
        self._names = tuple(robot_names)
        self._lifts = tuple(lifts)
        self._params = params
        self._berths = tuple({stop.level: cabin_berths(lift, stop.level, robot_radius,
                                                       params.berth_clearance)
                              for stop in lift.stops} for lift in self._lifts)
        self._state = self.DeclareAbstractState(Value[object](_Bank(
            tuple(_Cabin(lift.initial_level) for lift in self._lifts),
            (None,) * len(self._names))))
        self._requests = [self.DeclareAbstractInputPort(f"request_{name}",
                                                        Value[object](LiftRequest(name)))
                          for name in self._names]
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * len(self._names)))
        ticket = {self.abstract_state_ticket(self._state)}
        self.DeclareAbstractOutputPort("lift_state", lambda: Value[object](LiftState()),
                                       self._calc_lift_state, prerequisites_of_calc=ticket)
        self.DeclareAbstractOutputPort("relocations", lambda: Value[object](Relocations()),
                                       self._calc_relocations, prerequisites_of_calc=ticket)
        self.DeclareAbstractOutputPort("events", lambda: Value[object](()),
                                       self._calc_events, prerequisites_of_calc=ticket)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def capacity(self, lift: str) -> int:
        """How many robots ``lift``'s cabin carries."""
        k = next(i for i, spec in enumerate(self._lifts) if spec.name == lift)
        return min(len(berths) for berths in self._berths[k].values())

    def _bank(self, context) -> _Bank:
        return context.get_abstract_state(self._state).get_value()

    def _calc_lift_state(self, context, output):
        output.set_value(LiftState(tuple(
            LiftStatus(lift.name, c.level, c.riders, c.waiting, c.phase,
                       tuple(self._berths[k][_berths_level(c)][b] for b in c.berths),
                       c.trip())
            for k, (lift, c) in enumerate(zip(self._lifts, self._bank(context).cabins,
                                              strict=True)))))

    def _calc_relocations(self, context, output):
        output.set_value(Relocations(self._bank(context).moves))

    def _calc_events(self, context, output):
        output.set_value(self._bank(context).events)

    def _update(self, context, state):
        bank = self._bank(context)
        t = context.get_time()
        requests = {r.robot: r for r in (port.Eval(context) for port in self._requests)
                    if r.lift is not None}
        if not requests and all(c.phase == "idle" and not c.waiting for c in bank.cabins):
            return
        robots = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        events: list[LiftEvent] = []
        cabins = self._queued(list(bank.cabins), requests, robots, t, events)
        moves = list(bank.moves)
        cabins = [self._step(k, c, requests, robots, t, moves, events)
                  for k, c in enumerate(cabins)]
        new = _Bank(tuple(cabins), tuple(moves), bank.events + tuple(events))
        if new.cabins != bank.cabins or new.moves != bank.moves or events:
            state.get_mutable_abstract_state(self._state).set_value(new)

    def _queued(self, cabins: list[_Cabin], requests: dict[str, LiftRequest], robots, t,
                events: list[LiftEvent]) -> list[_Cabin]:
        """The cabins with their queues updated: robots no longer asking for a lift of the
        bank they queue for leave it; robots newly asking join the best lift's queue."""
        placed = set()
        for k, c in enumerate(cabins):
            waiting = tuple(name for name in c.waiting
                            if self._asks_for(requests.get(name), k))
            placed.update(waiting, c.riders)
            cabins[k] = replace(c, waiting=waiting) if waiting != c.waiting else c
        for name in self._names:
            request = requests.get(name)
            if request is None or name in placed:
                continue
            k = self._best_lift(request, cabins, robots[self._names.index(name), :2], t)
            cabins[k] = replace(cabins[k], waiting=cabins[k].waiting + (name,))
            events.append(LiftEvent(t, self._lifts[k].name, name, "request",
                                    request.from_level))
        return cabins

    def _asks_for(self, request: LiftRequest | None, k: int) -> bool:
        """Whether ``request`` may be served by lift ``k`` (one of its bank)."""
        return request is not None and k in self._bank_of(request)

    def _bank_of(self, request: LiftRequest) -> tuple[int, ...]:
        """The lifts that may serve ``request``: the one asked for and those serving both
        its levels whose cabins on its level lie within ``bank_distance`` of it."""
        asked = next(i for i, lift in enumerate(self._lifts) if lift.name == request.lift)
        there = self._lifts[asked].stop(request.from_level).cabin
        return tuple(i for i, lift in enumerate(self._lifts)
                     if i == asked or (lift.serves(request.from_level, request.to_level)
                                       and math.dist(lift.stop(request.from_level).cabin,
                                                     there) <= self._params.bank_distance))

    def _best_lift(self, request: LiftRequest, cabins: list[_Cabin], xy, t: float) -> int:
        """The lift of ``request``'s bank with the shortest expected wait for a robot at
        ``xy`` (m), the first in the building's order on a tie."""
        return min(self._bank_of(request),
                   key=lambda k: (round(self._expected_wait(k, cabins[k], request, xy, t), 6),
                                  k))

    def _expected_wait(self, k: int, c: _Cabin, request: LiftRequest, xy, t: float) -> float:
        """Seconds until a robot at ``xy`` asking ``request`` could board lift ``k``: the
        drive to its cabin at ``approach_speed``, the cabin's current trip (joining it if it
        goes the same way with a berth free), the trips of those queued ahead (as many
        per trip as it carries), and calling it to the robot's level."""
        params, lift = self._params, self._lifts[k]
        elevation = {stop.level: stop.elevation for stop in lift.stops}

        def ride(a, b):
            return ride_time(params, elevation[a], elevation[b]) if a != b else 0.0

        drive = math.dist(xy, lift.stop(request.from_level).cabin) / params.approach_speed
        capacity = self.capacity(lift.name)
        same_trip = (c.origin, c.destination) == (request.from_level, request.to_level)
        if c.phase == "idle":
            free_at, level = t, c.level
        elif c.phase in ("called", "open") and same_trip and len(c.riders) < capacity:
            return max(drive, c.until - t if c.phase == "called" else 0.0)
        else:
            left = (max(c.until - t, 0.0) if c.phase in ("called", "travel", "closing")
                    else 0.0)
            if c.phase in ("called", "open"):
                left += params.door_time + ride(c.origin, c.destination)
            free_at, level = t + left + params.door_time, c.destination
        trips = math.ceil(len(c.waiting) / capacity)
        cycle = (ride(request.from_level, request.to_level)
                 + ride(request.to_level, request.from_level) + 2.0 * params.door_time)
        ready = free_at - t + trips * cycle + ride(level, request.from_level)
        return max(drive, ready)

    def _step(self, k: int, c: _Cabin, requests: dict[str, LiftRequest], robots, t,
              moves, events) -> _Cabin:
        if c.phase == "idle" and c.waiting:
            first = requests[c.waiting[0]]
            c = replace(c, origin=first.from_level, destination=first.to_level,
                        phase="open" if c.level == first.from_level else "called")
            if c.phase == "called":
                c = replace(c, since=t, until=t + self._ride(k, c.level, c.origin))
        if c.phase in ("called", "open"):
            c = self._boarding(k, c, requests, robots, t, events)
        if c.phase == "called" and t >= c.until - 1e-9:
            c = replace(c, phase="open", level=c.origin)
        if c.phase == "open" and c.riders and len(c.boarded) == len(c.riders):
            c = replace(c, phase="closing", until=t + 0.5 * self._params.door_time)
        if c.phase == "closing" and t >= c.until - 1e-9:
            events += [LiftEvent(t, self._lifts[k].name, name, "depart", c.level)
                       for name in c.riders]
            c = replace(c, phase="travel", since=c.until, until=c.until + self._ride(
                k, c.origin, c.destination) - 0.5 * self._params.door_time)
        if c.phase == "travel" and t >= c.until - 1e-9:
            c = self._arrive(k, c, robots, t, moves, events)
        if c.phase == "out":
            c = self._leaving(k, c, robots, t, events)
        return c

    def _ride(self, k: int, a: str, b: str) -> float:
        lift = self._lifts[k]
        return ride_time(self._params, lift.stop(a).elevation, lift.stop(b).elevation)

    def _boarding(self, k: int, c: _Cabin, requests, robots, t, events) -> _Cabin:
        """Riders who stopped asking drop out; waiting robots with the cabin's trip take
        free berths; at the open doors, riders at their berths board, and ``board_wait``
        after the first did, those not aboard go back to the head of the queue."""
        keep = [i for i, name in enumerate(c.riders)
                if name in c.boarded or self._asks_for(requests.get(name), k)]
        riders = tuple(c.riders[i] for i in keep)
        berths = tuple(c.berths[i] for i in keep)
        free = [b for b in range(len(self._berths[k][c.origin])) if b not in berths]
        waiting = []
        for name in c.waiting:
            request = requests[name]
            if free and (request.from_level, request.to_level) == (c.origin, c.destination):
                riders, berths = riders + (name,), berths + (free.pop(0),)
            else:
                waiting.append(name)
        boarded, since = c.boarded, c.since
        if c.phase == "open":
            spots = self._berths[k][c.origin]
            for name, b in zip(riders, berths, strict=True):
                xy = robots[self._names.index(name), :2]
                if name not in boarded and math.dist(xy, spots[b]) <= \
                        self._params.board_tolerance:
                    since = since if boarded else t
                    boarded += (name,)
                    events.append(LiftEvent(t, self._lifts[k].name, name, "board", c.level))
            if boarded and t - since >= self._params.board_wait - 1e-9:
                late = tuple(name for name in riders if name not in boarded)
                keep = [i for i, name in enumerate(riders) if name in boarded]
                riders, berths = tuple(riders[i] for i in keep), tuple(berths[i] for i in keep)
                waiting = [*late, *waiting]
        if not riders:
            return replace(c, phase="idle" if c.phase == "open" else c.phase, riders=(),
                           berths=(), boarded=(), waiting=tuple(waiting))
        return replace(c, riders=riders, berths=berths, boarded=boarded, since=since,
                       waiting=tuple(waiting))

    def _arrive(self, k: int, c: _Cabin, robots, t, moves, events) -> _Cabin:
        """The riders moved by the offset between the cabins, headings kept, at rest."""
        lift = self._lifts[k]
        shift = np.subtract(lift.stop(c.destination).middle, lift.stop(c.origin).middle)
        for name in c.riders:
            i = self._names.index(name)
            pose = (float(robots[i, 0] + shift[0]), float(robots[i, 1] + shift[1]),
                    float(robots[i, 2]))
            moves[i] = (1 if moves[i] is None else moves[i][0] + 1, pose)
            events.append(LiftEvent(t, lift.name, name, "arrive", c.destination))
        return replace(c, phase="out", level=c.destination)

    def _leaving(self, k: int, c: _Cabin, robots, t, events) -> _Cabin:
        """Riders farther than ``leave_distance`` from both cabins' points have left; the
        cabin is free once all have."""
        lift = self._lifts[k]
        gone = [name for name in c.riders if all(
            math.dist(robots[self._names.index(name), :2], lift.stop(level).cabin)
            > self._params.leave_distance for level in (c.origin, c.destination))]
        if not gone:
            return c
        events += [LiftEvent(t, lift.name, name, "leave", c.level) for name in gone]
        keep = [i for i, name in enumerate(c.riders) if name not in gone]
        if not keep:
            return replace(c, phase="idle", riders=(), berths=(), boarded=())
        return replace(c, riders=tuple(c.riders[i] for i in keep),
                       berths=tuple(c.berths[i] for i in keep),
                       boarded=tuple(name for name in c.boarded if name not in gone))
