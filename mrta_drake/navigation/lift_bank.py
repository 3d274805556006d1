"""The lifts of a building as shared resources: one rider per cabin, first come first served,
and the ride that moves the rider to the cabin on the other level."""

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
    """How the lifts move. ``speed`` (m/s) and ``acceleration`` (m/s^2) are Open-RMF's
    Gazebo lift defaults; ``door_time`` (s) is the doors closing before and opening after a
    ride, half each; a holder within ``board_tolerance`` m of the cabin's point is aboard;
    a rider farther than ``leave_distance`` m from the cabin has left it."""

    speed: float = 2.0
    acceleration: float = 1.2
    door_time: float = 4.0
    board_tolerance: float = 0.5
    leave_distance: float = 2.0

    def __post_init__(self):
        require_positive(self, "speed", "acceleration", "board_tolerance", "leave_distance")
        require_non_negative(self, "door_time", unit=" s")


@dataclass(frozen=True)
class LiftStop:
    """Where a lift stops: on ``level`` (at ``elevation`` m) its cabin's roadway ``node`` is
    at ``cabin`` (x, y), world frame, m."""

    level: str
    cabin: tuple[float, float]
    elevation: float
    node: str


@dataclass(frozen=True)
class LiftSpec:
    """A lift ``name`` with its ``stops`` in level order, the cabin first at
    ``initial_level``."""

    name: str
    stops: tuple[LiftStop, ...]
    initial_level: str

    def stop(self, level: str) -> LiftStop:
        return next(stop for stop in self.stops if stop.level == level)


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
    """One lift's state: see ``LiftStatus``; ``origin`` and ``destination`` the holder's
    levels; ``until`` when the current call or ride phase ends (s)."""

    level: str
    holder: str | None = None
    waiting: tuple[str, ...] = ()
    phase: str = "idle"
    origin: str = ""
    destination: str = ""
    until: float = 0.0


@dataclass(frozen=True)
class _Bank:
    cabins: tuple[_Cabin, ...]
    moves: tuple[tuple[int, tuple[float, float, float]] | None, ...]
    events: tuple[LiftEvent, ...] = ()

    def __deepcopy__(self, memo):
        return self  # immutable


class LiftBank(LeafSystem):
    """The building's lifts (``lifts``), each a cabin one robot rides at a time.

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

    ``rate_hz`` times a second an unrestricted update, per lift: robots requesting it join
    its queue (a ``request`` event), those no longer requesting it leave; a free cabin goes
    to the first waiting robot (first empty to its level if elsewhere, taking
    ``ride_time``); the holder drives in (within ``board_tolerance`` of the cabin's point:
    ``board``), the doors close (half of ``door_time``: ``depart``) and at the end of the
    ride (``arrive``) the holder is relocated by the offset between the two cabins, heading
    kept; the cabin is free once the holder is ``leave_distance`` from both cabins
    (``leave``). A holder that stops asking before boarding gives the cabin up.
    """

    def __init__(self, robot_names: Sequence[str], lifts: Sequence[LiftSpec],
                 params: LiftParams = LiftParams(), *, rate_hz: float):
        super().__init__()
        self._names = tuple(robot_names)
        self._lifts = tuple(lifts)
        self._params = params
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

    def _bank(self, context) -> _Bank:
        return context.get_abstract_state(self._state).get_value()

    def _calc_lift_state(self, context, output):
        output.set_value(LiftState(tuple(
            LiftStatus(lift.name, c.level, c.holder, c.waiting, c.phase)
            for lift, c in zip(self._lifts, self._bank(context).cabins, strict=True))))

    def _calc_relocations(self, context, output):
        output.set_value(Relocations(self._bank(context).moves))

    def _calc_events(self, context, output):
        output.set_value(self._bank(context).events)

    def _update(self, context, state):
        bank = self._bank(context)
        t = context.get_time()
        requests = [port.Eval(context) for port in self._requests]
        robots = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        cabins, moves, events = [], list(bank.moves), []
        for lift, cabin in zip(self._lifts, bank.cabins, strict=True):
            cabin = self._step(lift, cabin, requests, robots, t, moves, events)
            cabins.append(cabin)
        new = _Bank(tuple(cabins), tuple(moves), bank.events + tuple(events))
        if new.cabins != bank.cabins or new.moves != bank.moves or events:
            state.get_mutable_abstract_state(self._state).set_value(new)

    def _step(self, lift: LiftSpec, c: _Cabin, requests, robots, t, moves, events) -> _Cabin:
        params = self._params
        asking = [r.robot for r in requests if r.lift == lift.name]
        waiting = tuple(name for name in c.waiting if name in asking)
        for name in asking:
            if name not in waiting and name != c.holder:
                waiting += (name,)
                events.append(LiftEvent(t, lift.name, name, "request",
                                        self._request(requests, name).from_level))
        c = replace(c, waiting=waiting)
        if c.phase == "idle" and c.waiting:
            holder, request = c.waiting[0], self._request(requests, c.waiting[0])
            c = replace(c, holder=holder, waiting=c.waiting[1:], origin=request.from_level,
                        destination=request.to_level)
            if c.level == c.origin:
                c = replace(c, phase="open")
            else:
                c = replace(c, phase="called", until=t + ride_time(
                    params, lift.stop(c.level).elevation, lift.stop(c.origin).elevation))
        if c.phase == "called" and t >= c.until - 1e-9:
            c = replace(c, phase="open", level=c.origin)
        if c.phase == "open":
            xy = robots[self._names.index(c.holder), :2]
            if c.holder not in asking:
                c = replace(c, phase="idle", holder=None)
            elif math.dist(xy, lift.stop(c.level).cabin) <= params.board_tolerance:
                events.append(LiftEvent(t, lift.name, c.holder, "board", c.level))
                c = replace(c, phase="closing", until=t + 0.5 * params.door_time)
        if c.phase == "closing" and t >= c.until - 1e-9:
            events.append(LiftEvent(t, lift.name, c.holder, "depart", c.level))
            c = replace(c, phase="travel", until=c.until + ride_time(
                params, lift.stop(c.origin).elevation, lift.stop(c.destination).elevation)
                - 0.5 * params.door_time)
        if c.phase == "travel" and t >= c.until - 1e-9:
            k = self._names.index(c.holder)
            shift = np.subtract(lift.stop(c.destination).cabin, lift.stop(c.origin).cabin)
            pose = (float(robots[k, 0] + shift[0]), float(robots[k, 1] + shift[1]),
                    float(robots[k, 2]))
            moves[k] = (1 if moves[k] is None else moves[k][0] + 1, pose)
            events.append(LiftEvent(t, lift.name, c.holder, "arrive", c.destination))
            c = replace(c, phase="out", level=c.destination)
        if c.phase == "out":
            xy = robots[self._names.index(c.holder), :2]
            if all(math.dist(xy, lift.stop(level).cabin) > params.leave_distance
                   for level in (c.origin, c.destination)):
                events.append(LiftEvent(t, lift.name, c.holder, "leave", c.level))
                c = replace(c, phase="idle", holder=None)
        return c

    @staticmethod
    def _request(requests, robot: str) -> LiftRequest:
        return next(r for r in requests if r.robot == robot)
