"""Recording what happened in a run, as it happens."""

import csv
import dataclasses
import json
import math
import os

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.navigation.standstills import waits_for
from mrta_drake.payloads import (
    PATH_FAILED,
    ROBOT_STATE_SIZE,
    ROBOT_STOPPED_SPEED,
    BackOffOrders,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    FleetPlan,
    HumanStates,
    LiftState,
    NetworkViews,
    QueueRequest,
    QueueState,
    RobotMode,
    RobotProgress,
    WaypointTarget,
)
from mrta_drake.results.deadlocks import stalled_waits
from mrta_drake.stack.fleet_inputs import PerRobotInputs
from mrta_drake.stack.sample_log import RowLog, TelemetryLog

# The modes as plain ints, for the per-robot loop of ``RunRecorder._modes``.
_IDLE, _DRIVE, _QUEUE, _SERVE = (int(mode) for mode in (
    RobotMode.IDLE, RobotMode.DRIVE, RobotMode.QUEUE, RobotMode.SERVE))


class RunRecorder(LeafSystem):
    """Samples the run at ``rate_hz`` (publish events only: it never changes the run).

    .. pydrake_system::

        name: RunRecorder
        input_ports:
        - robot_state
        - telemetry
        - paths
        - queue_state
        - plan
        - progress_<robot>
        - target_<robot>
        - queue_request_<robot>
        - fleet_progress (optional)
        - fleet_targets (optional)
        - fleet_queue_requests (optional)
        - human_states (optional)
        - human_active (optional)
        - allocator_events (optional)
        - disturbances (optional)
        - lift_state (optional)
        - lift_events (optional)
        - back_offs (optional)
        - network (optional)

    Keeps in memory, per sample: the time, the robot states (T, N, 4) [x, y, theta, v]
    (world frame, m, rad, m/s), the human positions (T, M, 2) (NaN while a human is not yet
    present), each robot's ``RobotMode`` (T, N) (``IDLE``, ``DRIVE``, ``QUEUE`` or ``SERVE``)
    and the controller telemetry; with a ``network`` (``NetworkViews``), the ages (s) of the
    states each robot has of each other one (``information_ages``, one row per sample). The
    samples are kept as numbers (``sample_log.RowLog`` and ``TelemetryLog``, sequences of
    rows), not as an object each, so an hour's run grows by its numbers alone. It also
    notes events (dicts, ``time`` the sample time, s):

    - ``plan``: the allocator's plan changed: ``revision`` and, per robot, its stops
      (``key``, ``task``, ``action``, ``location``, ``planned``: predicted completion, s).
    - ``start``: a robot began stop ``key`` (its ``current_stop``) at ``at`` (s): when it
      completed its previous stop if that is noted at the same sample, else the previous
      sample's time. (A sample at t sees the states as updated before t, so the change
      happened at or after the previous sample: exactly then when the waypoint generators
      update at the recorder's rate, as by default.)
    - ``arrival``: a robot completed stop ``key`` at ``at`` (s).
    - ``room``: a room's holder or waiting robots changed (a grant when ``holder`` is set).
    - ``planner_failure``: the planner failed for ``robots`` (``total`` so far).
    - ``controller_failure``: the controller braked ``failures`` robots at its last tick.
    - ``allocation``: an event from the allocator's ``events`` output, as ``event``.
    - ``disturbance``: a scheduled disturbance started or ended (``phase`` ``start`` or
      ``end``) at ``at`` (s): ``kind`` ``blockage`` (with ``name`` and ``box``),
      ``breakdown`` or ``outage`` (with ``robot``).
    - ``detour``: blockages (``blockages``, names) changed a robot's route at ``at`` (s);
      ``found`` False: no lane was left, it waits.
    - ``lift``: an event of the lift bank's ``events`` output (``LiftEvent``: ``lift``,
      ``robot``, ``kind``, ``level``, ``at`` s).
    - ``back_off``: the deadlock watchdog ordered ``robot`` to ``point`` (x, y) at ``at``
      until ``until`` (s), blocked by ``blockers`` since ``stalled_since`` (s); with
      ``releases`` (true, else absent) it gives way to break a gridlock of waits.

    With ``out_dir`` it appends every sample to ``timeline.csv`` and every event to
    ``events.jsonl`` as they happen, flushed, so a crash loses nothing.

    A robot's mode: ``IDLE`` without a current stop or an active target; ``QUEUE`` while it
    waits in some room's queue or for single-file segments and the wait leads somewhere, or
    for a lift or inside one (per ``lift_state``); ``SERVE`` while it holds its stop's room,
    drives to no waypoint after the current one and is within ``serve_radius`` m of it;
    ``DRIVE`` otherwise. A wait leads somewhere (``results.deadlocks.stalled_waits``)
    while each robot it waits for (the room's holder; the holders of the segments it asks
    for, or else the robots before it asking for one of them) moves (faster than
    ``ROBOT_STOPPED_SPEED``), serves, is at a lift or waits in a way that leads somewhere.
    A robot waiting for one that stands (e.g. parked on a segment it holds), or robots
    waiting for each other with none of them moving (a gridlock), are ``DRIVE``.

    Inputs: ``robot_state`` (4N), ``telemetry``, ``paths``, ``queue_state``, ``plan``,
    ``progress_<robot>``, ``target_<robot>`` and ``queue_request_<robot>`` per robot (or
    instead ``fleet_progress``, ``fleet_targets`` and ``fleet_queue_requests``, their
    tuples in robot order: ``stack.fleet_inputs``); optional (may
    stay unconnected): ``human_states``, ``human_active`` (M, 1 = present),
    ``allocator_events`` (a sequence of event objects; new ones are noted),
    ``disturbances``, ``lift_state`` (``LiftState``) and ``lift_events`` (a growing tuple
    of ``LiftEvent``), ``back_offs`` (``BackOffOrders``; its ``history`` grows).
    """

    def __init__(self, robot_names, humans=(), *, rate_hz: float, out_dir: str | None = None,
                 serve_radius: float = 1.0):
        super().__init__()
        self.robot_names = tuple(robot_names)
        self.human_names = tuple(h.name for h in humans)
        self._n = len(self.robot_names)
        self._out_dir = out_dir
        self._serve_radius = serve_radius
        self.DeclareVectorInputPort("robot_state", ROBOT_STATE_SIZE * self._n)
        self.DeclareAbstractInputPort("telemetry", _value(ControllerTelemetry()))
        self.DeclareAbstractInputPort("paths", _value(FleetPaths(())))
        self.DeclareAbstractInputPort("queue_state", _value(QueueState()))
        self.DeclareAbstractInputPort("plan", _value(FleetPlan(())))
        self._progress = PerRobotInputs(self, "progress", "progress", self.robot_names,
                                        RobotProgress)
        self._targets = PerRobotInputs(self, "target", "targets", self.robot_names,
                                       WaypointTarget)
        self._requests = PerRobotInputs(self, "queue_request", "queue_requests",
                                        self.robot_names, QueueRequest)
        self.DeclareAbstractInputPort("human_states", _value(HumanStates()))
        self.DeclareVectorInputPort("human_active", len(self.human_names))
        self.DeclareAbstractInputPort("allocator_events", _value(()))
        self.DeclareAbstractInputPort("disturbances", _value(Disturbances()))
        self.DeclareAbstractInputPort("lift_state", _value(LiftState()))
        self.DeclareAbstractInputPort("lift_events", _value(()))
        self.DeclareAbstractInputPort("network", _value(NetworkViews()))
        self._lift_events_seen = 0
        self.DeclareAbstractInputPort("back_offs", _value(BackOffOrders()))
        # Looked up once: by name, a lookup scans all (2N + 9) ports.
        self._ports = {port.get_name(): port for port in
                       (self.get_input_port(i) for i in range(self.num_input_ports()))}
        self.DeclarePeriodicPublishEvent(1.0 / rate_hz, 0.0, self._sample)
        self.DeclareForcedPublishEvent(self._sample)
        self.clear()

    def clear(self) -> None:
        """Forget everything recorded (before a new run with the same diagram)."""
        self.times = RowLog()
        self.robot_states = RowLog((self._n, ROBOT_STATE_SIZE))
        self.human_positions = RowLog((len(self.human_names), 2))
        self.modes = RowLog((self._n,), np.int8)
        self.telemetry = TelemetryLog()
        self.information_ages = RowLog((self._n * (self._n - 1),))
        self.events: list[dict] = []
        self._seen_visits = [0] * self._n
        self._seen_detours = [0] * self._n
        self._last_progress: list[RobotProgress | None] = [None] * self._n
        self._last_queues: QueueState | None = None
        self._disturbances: dict[tuple, dict] = {}
        self._current_keys: list[str | None] = [None] * self._n
        self._last_revision = None
        self._last_rooms: dict[int, tuple] = {}
        self._last_segments: tuple = ((), ())
        self._last_failures = 0
        self._allocator_events = ()
        self._back_offs_seen = 0
        self._last_time: float | None = None  # the last two samples' times (s)
        self._previous_time: float | None = None
        self._timeline = None
        self._event_file = None

    def close(self) -> None:
        for f in (self._timeline, self._event_file):
            if f is not None:
                f.close()
        self._timeline = self._event_file = None

    def _open_files(self) -> None:
        os.makedirs(self._out_dir, exist_ok=True)
        self._timeline = open(os.path.join(self._out_dir, "timeline.csv"), "w", newline="")
        self._csv = csv.writer(self._timeline)
        self._csv.writerow(["time", "robot", "x", "y", "theta", "v"])
        self._event_file = open(os.path.join(self._out_dir, "events.jsonl"), "w")

    def _event(self, event: dict) -> None:
        self.events.append(event)
        if self._event_file is not None:
            self._event_file.write(json.dumps(_jsonable(event)) + "\n")
            self._event_file.flush()

    def _sample(self, context) -> None:
        t = context.get_time()
        if self._last_time is not None and t <= self._last_time:
            return  # the forced publish at the end of a run repeats the last periodic one
        self._previous_time, self._last_time = self._last_time, t
        if self._out_dir is not None and self._timeline is None:
            self._open_files()
        states = self._ports["robot_state"].Eval(context).reshape(self._n, -1)  # Eval copies
        self.times.append(t)
        self.robot_states.append(states)
        humans_port = self._ports["human_states"]
        if humans_port.HasValue(context):
            positions = np.array(humans_port.Eval(context).positions, dtype=float)
            active_port = self._ports["human_active"]
            if active_port.HasValue(context):
                positions[active_port.Eval(context) < 0.5] = np.nan
            self.human_positions.append(positions)
        telemetry = self._ports["telemetry"].Eval(context)
        self.telemetry.append(telemetry)
        network = self._ports["network"]
        if network.HasValue(context):
            self.information_ages.append(t - network.Eval(context).sent_at[
                ~np.eye(self._n, dtype=bool)])
        if self._timeline is not None:
            stamp = f"{t:.3f}"
            self._csv.writerows([stamp, name] + [f"{v:.4f}" for v in row]
                                for name, row in zip(self.robot_names, states.tolist(),
                                                     strict=True))
            self._timeline.flush()
        queues = self._ports["queue_state"].Eval(context)
        progress = self._progress.values(context)
        self.modes.append(self._modes(context, states, queues, progress))
        self._note_plan(context, t)
        self._note_progress(progress, t)
        self._note_rooms(queues, t)
        self._note_failures(context, t, telemetry)
        self._note_allocator_events(context, t)
        self._note_disturbances(context, t)
        self._note_lift_events(context, t)
        self._note_back_offs(context, t)

    def _modes(self, context, states: np.ndarray, queues: QueueState,
               progress: tuple[RobotProgress, ...]) -> np.ndarray:
        waiting = {robot for queue in queues.rooms for robot in queue.waiting}
        at_lifts = set()
        if self._ports["lift_state"].HasValue(context):
            for lift in self._ports["lift_state"].Eval(context).lifts:
                at_lifts.update(lift.waiting)
                if lift.phase != "out":
                    at_lifts.update(lift.riders)
        waiting |= at_lifts
        holders = {queue.room: queue.holder for queue in queues.rooms}
        modes = [_IDLE] * self._n  # plain ints: numpy scalars and IntEnum members are slow
        targets = self._targets.values(context)
        segment_waiting = queues.segment_waiting
        for k, (name, robot, target) in enumerate(zip(self.robot_names, progress, targets,
                                                      strict=True)):
            stop = robot.current_stop
            if stop is None:
                continue
            if name in segment_waiting:  # holding back for a single-file stretch
                modes[k] = _QUEUE
                continue
            if not target.active:
                continue
            if name in waiting:
                modes[k] = _QUEUE
            elif (holders.get(stop.location) == name and target.next is None
                  and target.current is not None
                  and math.dist(states[k, :2], target.current) <= self._serve_radius):
                modes[k] = _SERVE
            else:
                modes[k] = _DRIVE
        if _QUEUE not in modes:
            return np.array(modes, dtype=np.int8)  # no wait to test for a gridlock
        moving = (np.abs(states[:, 3]) > ROBOT_STOPPED_SPEED).tolist()
        live = at_lifts.union(name for k, name in enumerate(self.robot_names)
                              if moving[k] or modes[k] == _SERVE)
        stalled = stalled_waits(waits_for(queues, self._requests.values(context)), live)
        for k, name in enumerate(self.robot_names):
            if modes[k] == _QUEUE and name in stalled:
                modes[k] = _DRIVE  # a gridlock, not a queue
        return np.array(modes, dtype=np.int8)

    def _note_plan(self, context, t: float) -> None:
        plan = self._ports["plan"].Eval(context)
        if not plan.plans or plan.revision == self._last_revision:
            return
        self._last_revision = plan.revision
        self._event({"time": t, "type": "plan", "revision": plan.revision, "plans": {
            p.robot: [{"key": s.key, "task": s.task, "action": s.action,
                       "location": s.location, "planned": s.planned_time} for s in p.stops]
            for p in plan.plans}})

    def _note_progress(self, progresses: tuple[RobotProgress, ...], t: float) -> None:
        previous = t if self._previous_time is None else self._previous_time
        for k, (name, progress) in enumerate(zip(self.robot_names, progresses, strict=True)):
            if progress is self._last_progress[k]:
                continue  # immutable: nothing new since the last sample
            self._last_progress[k] = progress
            began = previous
            for visit in progress.visits[self._seen_visits[k]:]:
                self._event({"time": t, "type": "arrival", "robot": name, "key": visit.key,
                             "location": visit.location, "at": visit.time,
                             "task": visit.task, "action": visit.action})
                began = visit.time
            self._seen_visits[k] = len(progress.visits)
            for detour in progress.detours[self._seen_detours[k]:]:
                self._event({"time": t, "type": "detour", "robot": name, "at": detour.time,
                             "blockages": list(detour.blockages), "found": detour.found})
            self._seen_detours[k] = len(progress.detours)
            stop = progress.current_stop
            key = None if stop is None else stop.key
            if key is not None and key != self._current_keys[k]:
                self._event({"time": t, "type": "start", "robot": name, "key": key,
                             "at": began, "location": stop.location, "task": stop.task,
                             "action": stop.action})
            self._current_keys[k] = key

    def _note_rooms(self, queues: QueueState, t: float) -> None:
        if queues is self._last_queues:
            return  # immutable: nothing new since the last sample
        self._last_queues = queues
        for queue in queues.rooms:
            now = (queue.holder, queue.waiting)
            if self._last_rooms.get(queue.room) != now:
                self._last_rooms[queue.room] = now
                self._event({"time": t, "type": "room", "room": queue.room,
                             "holder": queue.holder, "waiting": list(queue.waiting)})
        if queues.segments and (queues.segments, queues.segment_waiting) != self._last_segments:
            self._last_segments = (queues.segments, queues.segment_waiting)
            self._event({"time": t, "type": "segments", "waiting": list(queues.segment_waiting),
                         "held": {str(k): list(hold.holders)
                                  for k, hold in enumerate(queues.segments) if hold.holders}})

    def _note_failures(self, context, t: float, telemetry: ControllerTelemetry) -> None:
        paths = self._ports["paths"].Eval(context)
        if paths.failures > self._last_failures:
            failed = [p.robot for p in paths.paths if p.status == PATH_FAILED]
            self._event({"time": t, "type": "planner_failure", "robots": failed,
                         "total": paths.failures})
            self._last_failures = paths.failures
        if telemetry.failures:
            self._event({"time": t, "type": "controller_failure",
                         "failures": int(telemetry.failures)})

    def _note_allocator_events(self, context, t: float) -> None:
        port = self._ports["allocator_events"]
        if not port.HasValue(context):
            return
        events = tuple(port.Eval(context))
        seen = self._allocator_events
        if events is seen or events == seen:
            return
        # A growing log gets its new tail noted; anything else is noted whole.
        new = events[len(seen):] if events[:len(seen)] == seen else events
        for event in new:
            self._event({"time": t, "type": "allocation", "event": _as_dict(event)})
        self._allocator_events = events

    def _note_lift_events(self, context, t: float) -> None:
        port = self._ports["lift_events"]
        if not port.HasValue(context):
            return
        events = port.Eval(context)
        for event in events[self._lift_events_seen:]:
            self._event({"time": t, "type": "lift", "lift": event.lift, "robot": event.robot,
                         "kind": event.kind, "level": event.level, "at": event.time})
        self._lift_events_seen = len(events)

    def _note_back_offs(self, context, t: float) -> None:
        port = self._ports["back_offs"]
        if not port.HasValue(context):
            return
        history = port.Eval(context).history
        if len(history) == self._back_offs_seen:
            return  # nothing new (the history only grows)
        for order in history[self._back_offs_seen:]:
            self._event({"time": t, "type": "back_off", "robot": order.robot,
                         "point": list(order.point), "at": order.issued, "until": order.until,
                         "blockers": list(order.blockers),
                         "stalled_since": order.stalled_since}
                        | ({"releases": True} if order.releases else {}))
        self._back_offs_seen = len(history)

    def _note_disturbances(self, context, t: float) -> None:
        port = self._ports["disturbances"]
        if not port.HasValue(context):
            return
        active = port.Eval(context)
        now = {("blockage", b.name): {"kind": "blockage", "name": b.name, "box": list(b.box),
                                      "start": b.start, "end": b.end}
               for b in active.blockages}
        for kind, entries in (("breakdown", active.breakdowns), ("outage", active.outages)):
            now |= {(kind, e.robot): {"kind": kind, "robot": self.robot_names[e.robot],
                                      "start": e.start, "end": e.end} for e in entries}
        for key, entry in self._disturbances.items():
            if key not in now:
                self._event({"time": t, "type": "disturbance", "phase": "end",
                             "at": entry["end"]} | _without(entry, "start", "end"))
        for key, entry in now.items():
            if key not in self._disturbances:
                self._event({"time": t, "type": "disturbance", "phase": "start",
                             "at": entry["start"]} | _without(entry, "start", "end"))
        self._disturbances = now

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """times (T,), robot states (T, N, 4), human positions (T, M, 2)."""
        times = self.times.array()
        humans = (self.human_positions.array() if self.human_positions
                  else np.zeros((len(times), 0, 2)))
        return times, self.robot_states.array(), humans

    def mode_array(self) -> np.ndarray:
        """(T, N) int8: each robot's ``RobotMode`` at each sample."""
        return self.modes.array()


def _value(example):
    return Value[object](example)


def _without(entry: dict, *keys) -> dict:
    return {k: v for k, v in entry.items() if k not in keys}


def _as_dict(event) -> dict:
    """An allocator event as a plain dict: dataclass fields plus ``kind`` (its class name)."""
    if dataclasses.is_dataclass(event):
        return {"kind": type(event).__name__} | {
            f.name: getattr(event, f.name) for f in dataclasses.fields(event)}
    if isinstance(event, dict):
        return dict(event)
    return {"kind": type(event).__name__, "value": str(event)}


def _jsonable(value):
    """``value`` with non-finite floats as None, tuples as lists, numpy scalars as Python
    numbers, dataclasses as dicts and anything else unknown as its string."""
    if isinstance(value, float | np.floating):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, bool | int | str | type(None)):
        return value
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_jsonable(v) for v in value]
    if dataclasses.is_dataclass(value):
        return _jsonable(_as_dict(value))
    return str(value)
