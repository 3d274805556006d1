"""First-come first-served queues for all rooms and single-file segments: one holder per
room, or segment, at a time."""

import dataclasses
from collections.abc import Mapping, Sequence

from pydrake.common.value import Value
from pydrake.systems.framework import EventStatus, LeafSystem

from mrta_drake.payloads import (
    FREE_SEGMENT,
    QueueRequest,
    QueueState,
    RoomQueue,
    SegmentHold,
)
from mrta_drake.stack.fleet_inputs import PerRobotInputs


class RoomQueues(LeafSystem):
    """Grants each room to one robot at a time, in request order.

    .. pydrake_system::

        name: RoomQueues
        input_ports:
        - request_<robot>
        - fleet_queue_requests (optional)
        output_ports:
        - queue_state

    Inputs: ``request_<robot>`` (abstract ``QueueRequest``), one per robot, in
    ``robot_names`` order, or instead ``fleet_queue_requests``, their tuple in that order
    (``stack.fleet_inputs``).
    Output: ``queue_state`` (abstract ``QueueState``), one ``RoomQueue`` per room in ``rooms``
    order, from the state (no direct feedthrough).

    ``rate_hz`` times a second an unrestricted update applies all requests, in this order:

    1. Release: a robot naming room r in ``release`` gives r up if, and only if, it holds r.
       Anything else (not the holder, not a known room) changes nothing.
    2. Leave: a waiting robot whose ``room`` no longer names the room it waits for leaves
       that queue. A holder keeps its room until it releases it, whatever ``room`` says.
    3. Join: a robot naming room r that neither holds r nor waits for it joins r's tail.
       A room not in ``rooms`` is ignored.
    4. Grant: a room without a holder goes to the head of its waiting robots.

    Robots that join in the same update join in robot order, which makes ties deterministic.
    Queues are unbounded: which physical slot a waiting robot uses is the waypoint
    generator's business (robots beyond the last slot wait behind it). ``holders`` optionally
    names robots that hold rooms at the start (e.g. robots that start inside them).

    The ``segments`` single-file segments (0 .. segments - 1) are granted in the same update,
    after the rooms, from each request's ``segments`` (the set the robot wants now):

    1. Release: a holder that no longer names a segment gives it up. Robots holding a
       segment, alone or together, that all name it one way take that way (they turn in
       it: two robots standing in a dead end that both want out leave it).
    2. Wait: a robot naming a segment it does not hold waits (in the order it first did so;
       new ones in robot order, those standing in one they name first: at the start a
       robot standing in a segment asks for it at the same instant as one driving in);
       one that no longer does stops waiting.
    3. Grant: robots that hold some of the segments they name (they stand in them) first,
       then the others, each in waiting order: a robot gets all the segments it names at
       once when each is free or held by robots driving it the same way (only by itself
       for the ``exclusive`` segments, where robots stop, when it or a holder names the
       segment in ``stops``: it will stand there; robots that only drive through follow
       each other in), and, unless it holds some
       already, none is named by a robot before it still waiting; else it gets none. (A
       robot standing in a segment goes as soon as its way is free: one waiting before it
       may wait for the very segment it stands in.) A robot waiting before it keeps its
       turn only while that robot does not wait, through others, for this one: for the
       holders of the segments it cannot have, for the robots before it whose turn it
       keeps, for the holder of the room it queues for (office seed 3: a room's holder,
       leaving away from its queue, kept behind a robot that waited for the segment in
       which the robot at the room's head slot stood: a gridlock). A robot outside a
       segment where it would stop (``stops``) waits while a robot that holds the room it
       asks for (on its way in) waits for that segment: stopped there, on the way to that
       room's queue, it would keep the holder out for good.
    4. Each segment names the robots still waiting that name it (``SegmentHold.waiting``):
       a robot without a task standing in one drives out of the way (``WaypointPolicy``).

    All or nothing, so a robot that asks for every segment of a single-file stretch at its
    start never holds one part of it while waiting for another part; robots driving one way
    may follow each other in, never meet one driving the other way, and never follow one
    into a segment where it stops and may turn.
    """

    def __init__(
        self,
        robot_names: Sequence[str],
        rooms: Sequence[int],
        *,
        rate_hz: float,
        holders: Mapping[int, str] | None = None,
        segments: int = 0,
        exclusive: frozenset[int] = frozenset(),
    ):
        super().__init__()
        holders = dict(holders or {})
        for room, robot in holders.items():
            if room not in rooms or robot not in robot_names:
                raise ValueError(f"initial holder {robot!r} of room {room}: unknown robot or room")
        self._robots = tuple(robot_names)
        self._rooms = tuple(rooms)
        self._segments = segments
        self._exclusive = frozenset(exclusive)
        initial = QueueState(tuple(RoomQueue(room, holders.get(room)) for room in self._rooms),
                             segments=(FREE_SEGMENT,) * segments)
        self._state_index = self.DeclareAbstractState(Value[object](initial))
        self._requests = PerRobotInputs(self, "request", "queue_requests", self._robots,
                                        QueueRequest)
        self.DeclareStateOutputPort("queue_state", self._state_index)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def get_request_input_port(self, robot: str):
        return self._requests.ports[self._robots.index(robot)]

    def _update(self, context, state) -> EventStatus:
        old = context.get_abstract_state(self._state_index).get_value()
        requests = self._requests.values(context)
        new = self._applied(old, requests) if self._changes_anything(old, requests) else old
        if self._segments:
            holds, waiting = self._segments_applied(old, requests, new.rooms)
            if holds != old.segments or waiting != old.segment_waiting:
                new = dataclasses.replace(new, segments=holds, segment_waiting=waiting)
        if new is old:  # unchanged: Drake applies an instant's updates only if one changed
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state_index).set_value(new)
        return EventStatus.Succeeded()

    def _segments_applied(self, old: QueueState, requests: Sequence[QueueRequest],
                          rooms: Sequence[RoomQueue]
                          ) -> tuple[tuple[SegmentHold, ...], tuple[str, ...]]:
        """The segments' holders and waiting robots after ``requests`` (class docstring);
        ``rooms``: the rooms' queues after this update's room rules."""
        wanted = {robot: dict(request.segments)
                  for robot, request in zip(self._robots, requests, strict=True)}
        stops = {robot: set(request.stops).intersection(self._exclusive)
                 for robot, request in zip(self._robots, requests, strict=True)}
        holds = []
        for k, hold in enumerate(old.segments):
            holders = tuple(r for r in hold.holders if k in wanted[r])
            ways = {wanted[r][k] for r in holders}
            holds.append(SegmentHold(holders, ways.pop() if len(ways) == 1 else hold.forward))

        def needs(robot):
            return any(robot not in holds[k].holders for k in wanted[robot])

        def alone(robot, k):
            """Whether ``robot`` or a holder of segment ``k`` stops in it (class docstring)."""
            return k in stops[robot] or any(k in stops[r] for r in holds[k].holders)

        def blocked(robot):
            """The other robots holding segments ``robot`` names and cannot have now."""
            return {r for k, way in wanted[robot].items() if not (
                set(holds[k].holders) <= {robot}
                or (not alone(robot, k) and holds[k].forward == way))
                for r in holds[k].holders if r != robot}

        standing = {robot: set(request.standing)
                    for robot, request in zip(self._robots, requests, strict=True)}
        order = [r for r in old.segment_waiting if needs(r)]
        new = [r for r in self._robots if r not in order and needs(r)]
        order += sorted(new, key=lambda r: not standing[r].intersection(wanted[r]))
        # Whom each robot waits for (class docstring), the turns kept added as they come.
        waits_for = {robot: blocked(robot) for robot in order}
        for queue in rooms:
            for robot in queue.waiting if queue.holder is not None else ():
                waits_for.setdefault(robot, set()).add(queue.holder)

        def reaches(start, goal):
            seen, todo = set(), [start]
            while todo:
                robot = todo.pop()
                if robot == goal:
                    return True
                if robot not in seen:
                    seen.add(robot)
                    todo.extend(waits_for.get(robot, ()))
            return False

        inside = [r for r in order if any(r in holds[k].holders for k in wanted[r])]
        order = inside + [r for r in order if r not in inside]
        asked = {robot: request.room
                 for robot, request in zip(self._robots, requests, strict=True)}
        entering = {queue.holder for queue in rooms if queue.holder is not None
                    and asked[queue.holder] == queue.room} - set(inside)
        waiting, named = [], {}  # named: segment -> the robots still waiting that name it
        for robot in order:
            turns = set() if robot in inside else {
                r for k in wanted[robot] for r in named.get(k, ()) if not reaches(r, robot)}
            if robot not in inside and robot not in entering:
                turns |= {h for h in entering for k in stops[robot]
                          if k in wanted[robot] and k in wanted[h]
                          and h not in holds[k].holders}
            if not blocked(robot) and not turns:
                for k, way in wanted[robot].items():
                    if robot not in holds[k].holders:
                        holds[k] = SegmentHold((*holds[k].holders, robot), way)
                for other in waiting:  # who now waits for it
                    waits_for[other] = blocked(other) | waits_for[other]
            else:
                waiting.append(robot)
                waits_for[robot] = waits_for.get(robot, set()) | turns
                for k in wanted[robot]:
                    named.setdefault(k, []).append(robot)
        for k, robots in named.items():
            holds[k] = dataclasses.replace(holds[k], waiting=tuple(robots))
        return tuple(holds), tuple(waiting)

    def _changes_anything(self, old: QueueState, requests: Sequence[QueueRequest]) -> bool:
        """False if applying ``requests`` to ``old`` gives ``old`` itself (the hot path: most
        updates change nothing); True if it may not (a holder releasing and asking again for
        the same room gets it back)."""
        queues = {q.room: q for q in old.rooms}
        for robot, request in zip(self._robots, requests, strict=True):
            released = queues.get(request.release)
            if released is not None and released.holder == robot:
                return True
            wanted = queues.get(request.room)
            if wanted is not None and wanted.holder != robot and robot not in wanted.waiting:
                return True
        room_of = {robot: request.room
                   for robot, request in zip(self._robots, requests, strict=True)}
        return any((q.holder is None and q.waiting)
                   or any(room_of[robot] != q.room for robot in q.waiting)
                   for q in old.rooms)

    def _applied(self, old: QueueState, requests: Sequence[QueueRequest]) -> QueueState:
        holder = {q.room: q.holder for q in old.rooms}
        waiting = {q.room: list(q.waiting) for q in old.rooms}
        for robot, request in zip(self._robots, requests, strict=True):
            if request.release is not None and holder.get(request.release) == robot:
                holder[request.release] = None
        for robot, request in zip(self._robots, requests, strict=True):
            for room, queue in waiting.items():
                if room != request.room and robot in queue:
                    queue.remove(robot)
        for robot, request in zip(self._robots, requests, strict=True):
            room = request.room
            if room in waiting and holder[room] != robot and robot not in waiting[room]:
                waiting[room].append(robot)
        for room, queue in waiting.items():
            if holder[room] is None and queue:
                holder[room] = queue.pop(0)
        return dataclasses.replace(old, rooms=tuple(
            RoomQueue(room, holder[room], tuple(waiting[room])) for room in self._rooms))
