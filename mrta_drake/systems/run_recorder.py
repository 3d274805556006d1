"""Recording what happened in a run, as it happens."""

import csv
import json
import math
import os

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.payloads import (
    PATH_FAILED,
    ROBOT_STATE_SIZE,
    ControllerTelemetry,
    FleetPaths,
    FleetPlan,
    HumanStates,
    QueueState,
    RobotProgress,
)


class RunRecorder(LeafSystem):
    """Samples the run at a fixed rate (publish events only: it never changes the run).

    Keeps in memory the robot states (T, N, 4), human positions (T, M, 2) and controller
    telemetry, and notes events: allocator plan revisions, room grants, arrivals at stops,
    planner failures. With ``out_dir`` it also appends every sample to ``timeline.csv`` and
    every event to ``events.jsonl`` as they happen, flushed, so a crash loses nothing.

    Inputs: ``robot_state`` (4N), ``telemetry``, ``paths``, ``queue_state``, ``plan``,
    ``progress_<robot>`` per robot, ``human_states`` (optional).
    """

    def __init__(self, robot_names, humans=(), rate_hz: float = 10.0, out_dir: str | None = None):
        super().__init__()
        self.robot_names = tuple(robot_names)
        self.human_names = tuple(h.name for h in humans)
        self._n = len(self.robot_names)
        self._out_dir = out_dir
        self.DeclareVectorInputPort("robot_state", ROBOT_STATE_SIZE * self._n)
        self.DeclareAbstractInputPort("telemetry", _value(ControllerTelemetry()))
        self.DeclareAbstractInputPort("paths", _value(FleetPaths(())))
        self.DeclareAbstractInputPort("queue_state", _value(QueueState()))
        self.DeclareAbstractInputPort("plan", _value(FleetPlan(())))
        for name in self.robot_names:
            self.DeclareAbstractInputPort(f"progress_{name}", _value(RobotProgress(name)))
        self.DeclareAbstractInputPort("human_states", _value(HumanStates()))
        self.DeclarePeriodicPublishEvent(1.0 / rate_hz, 0.0, self._sample)
        self.DeclareForcedPublishEvent(self._sample)
        self.clear()

    def clear(self) -> None:
        """Forget everything recorded (before a new run with the same diagram)."""
        self.times: list[float] = []
        self.robot_states: list[np.ndarray] = []
        self.human_positions: list[np.ndarray] = []
        self.telemetry: list[ControllerTelemetry] = []
        self.events: list[dict] = []
        self._seen_visits = [0] * self._n
        self._last_revision = None
        self._last_holders: dict[int, str | None] = {}
        self._last_failures = 0
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
            self._event_file.write(json.dumps(event, default=_jsonable) + "\n")
            self._event_file.flush()

    def _sample(self, context) -> None:
        t = context.get_time()
        if self.times and t <= self.times[-1]:
            return  # the forced publish at the end of a run repeats the last periodic one
        if self._out_dir is not None and self._timeline is None:
            self._open_files()
        states = self.GetInputPort("robot_state").Eval(context).reshape(self._n, -1).copy()
        self.times.append(t)
        self.robot_states.append(states)
        humans_port = self.GetInputPort("human_states")
        if humans_port.HasValue(context):
            self.human_positions.append(np.array(humans_port.Eval(context).positions))
        telemetry = self.GetInputPort("telemetry").Eval(context)
        self.telemetry.append(telemetry)
        if self._timeline is not None:
            for name, row in zip(self.robot_names, states, strict=True):
                self._csv.writerow([f"{t:.3f}", name] + [f"{v:.4f}" for v in row])
            self._timeline.flush()
        self._note_events(context, t)

    def _note_events(self, context, t: float) -> None:
        plan = self.GetInputPort("plan").Eval(context)
        if plan.plans and plan.revision != self._last_revision:
            self._last_revision = plan.revision
            self._event({"time": t, "type": "plan", "revision": plan.revision,
                         "plans": {p.robot: [s.key for s in p.stops] for p in plan.plans}})
        for k, name in enumerate(self.robot_names):
            progress = self.GetInputPort(f"progress_{name}").Eval(context)
            for visit in progress.visits[self._seen_visits[k]:]:
                self._event({"time": t, "type": "arrival", "robot": name, "key": visit.key,
                             "location": visit.location, "at": visit.time,
                             "task": visit.task, "action": visit.action})
            self._seen_visits[k] = len(progress.visits)
        for queue in self.GetInputPort("queue_state").Eval(context).rooms:
            if self._last_holders.get(queue.room) != queue.holder:
                self._last_holders[queue.room] = queue.holder
                self._event({"time": t, "type": "room", "room": queue.room,
                             "holder": queue.holder, "waiting": list(queue.waiting)})
        paths = self.GetInputPort("paths").Eval(context)
        if paths.failures > self._last_failures:
            failed = [p.robot for p in paths.paths if p.status == PATH_FAILED]
            self._event({"time": t, "type": "planner_failure", "robots": failed,
                         "total": paths.failures})
            self._last_failures = paths.failures

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """times (T,), robot states (T, N, 4), human positions (T, M, 2)."""
        times = np.array(self.times)
        states = (np.array(self.robot_states) if self.robot_states
                  else np.zeros((0, self._n, ROBOT_STATE_SIZE)))
        humans = (np.array(self.human_positions) if self.human_positions
                  else np.zeros((len(times), 0, 2)))
        return times, states, humans


def _value(example):
    return Value[object](example)


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, np.generic):
        return value.item()
    return str(value)
