"""The figures of one run: what ``summary.json`` holds and ``mrta-sim report`` prints.

``summarize`` reads a finished run's recorder. Distances are in m (surface to surface for
clearances), times in s of simulation time unless named ``wall``/``cpu``. The keys:

- ``scenario``, ``scenario_hash``, ``seed``, ``versions``, ``duration`` (simulated),
  ``wall_time``, ``cpu_time``, ``real_time_factor`` (simulated / wall); ``interrupted``
  (added by ``stack.simulate``): True when the run was stopped (Ctrl-C, SIGTERM) before
  the duration asked for, which ``duration`` then is not: it is the simulated time reached.
- ``tasks``: ``timing.task_totals`` plus ``per_task``: ``timing.task_rows``.
- ``legs``: ``timing.leg_rows``, predicted against actual duration of every completed stop.
- ``predictions``: how well the allocator's predictions held (``predictions.predictions``):
  drop-off and leg errors, broken promises, re-plans on drift and their reasons.
- ``robots``: per robot ``distance``, ``busy_time`` (a stop to do: driving or serving),
  ``queue_time`` (waiting in a room queue), ``idle_time`` (nothing to do),
  ``stops_completed``, ``planner_failures`` (planner failure reports naming it),
  ``final_pose`` [x, y, theta].
- ``safety``: smallest robot-robot, robot-wall and robot-human clearance (``min_*``, None
  when there is no such pair) with when (``*_time``) and who (``*_between``); contact
  onsets (``*_contacts``); ``robot_wall_close_time``: robot-seconds with a robot's
  clearance to walls below ``robot_wall_close_distance``, half the controller's wall safety
  distance (``controller_wall_safety``); from the
  controller telemetry at the recorder's samples: ``max_cbf_slack`` (the largest CBF row
  relaxation, scaled rows, m/s^2) and ``cbf_slack_time`` (time with some slack >
  ``SLACK_TOLERANCE``).
- ``humans``: ``human_metrics.HumanMetrics`` fields, or None without humans.
- ``deadlocks``: ``count``, the detection settings and ``episodes`` (see ``deadlocks``).
- ``allocations``: from the allocator's events (when it reports them): ``count``,
  ``statuses`` (count per allocation status), ``predicted_late`` and ``conflicts`` (task ids
  any allocation predicted late or proved unable to be on time together) and
  ``solve_time`` (wall-clock s, summed).
- ``planner_failures``: the planner's failure count; ``controller_failures``: robots braked
  on solver failure, summed over the recorder's samples (the controller ticks faster, so
  this undercounts).
- ``physics_contacts``: with the physics robots block, the plant's contacts
  (``ContactRecorder.summary``: count, pairs of bodies by name, impulse, largest force and
  penetration); None with the kinematic one.
- ``disturbances``: one entry per scheduled disturbance (blockages, then breakdowns, then
  outages, each in scenario order) with its ``kind``, ``start`` and ``end`` (None: open
  ended): a blockage's ``name``, ``box``, ``robots_rerouted`` (given a new route around or
  back through it), ``robots_waited`` (found no lane left) and ``detours`` (route changes
  it caused); a breakdown's ``robot``, ``removed_at`` (when the allocator took it out of the
  fleet, None if it never did), ``tasks_reassigned`` and ``tasks_failed`` (items lost with
  it); an outage's ``robot`` and ``min_robot_clearance`` (to any other robot while cut off,
  m; None without samples).
- ``lifts``: per lift (a building run across levels), ``rides`` (arrivals), and the
  ``mean_wait`` and ``max_wait`` (s) from a robot's request to its boarding; empty without
  lifts. A robot's ``distance`` leaves out the jump of a lift ride (a step longer than
  ``RELOCATION_STEP``).
- ``back_offs``: the deadlock watchdog's orders (recorder ``back_off`` events): ``count``,
  ``robots`` (orders per robot ordered aside) and ``releases`` (those that broke a
  gridlock of waits); 0 without the watchdog.
- ``communication``: with a network (``communication:`` not ideal), the age of information
  and the time robots' views of their clusters disagreed and followers braked for want of a
  command (``communication.communication_metrics``); None when ideal.
"""

import dataclasses
import hashlib
import platform
from collections import Counter
from importlib import metadata

import numpy as np

from mrta_drake.payloads import RobotMode
from mrta_drake.results.clearances import clearances
from mrta_drake.results.communication import communication_metrics
from mrta_drake.results.deadlocks import (
    NEIGHBOUR_RANGE,
    PROGRESS_DISTANCE,
    STUCK_TIME,
    find_deadlocks,
)
from mrta_drake.results.human_metrics import human_metrics
from mrta_drake.results.predictions import predictions
from mrta_drake.results.timing import leg_rows, task_rows, task_totals
from mrta_drake.stack.blocks import resolve_block

SLACK_TOLERANCE = 1e-6  # CBF slack above this counts as a relaxed constraint
DEFAULT_WALL_SAFETY = 0.6  # m, robot centre to wall, for a controller without one

RELOCATION_STEP = 10.0  # m in one sample: further than any robot drives, so a lift ride


def scenario_hash(scenario) -> str:
    """A short stable hash of the loaded scenario (its dataclass repr)."""
    return hashlib.sha256(repr(scenario).encode()).hexdigest()[:16]


def _versions() -> dict:
    versions = {"python": platform.python_version()}
    for package in ("mrta-drake", "drake", "numpy", "z3-solver"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return versions


def summarize(stack, duration: float, wall_time: float, cpu_time: float) -> dict:
    """The summary of the run recorded by ``stack.recorder`` (see the module docstring)."""
    scenario, recorder = stack.scenario, stack.recorder
    times, states, humans = recorder.arrays()
    modes = recorder.mode_array()
    names = list(recorder.robot_names)
    radii = np.array([r.radius for r in scenario.robots])
    xy = states[..., :2]
    human_radii = (np.asarray(stack.humans.human_radii) if stack.humans is not None
                   else np.zeros(humans.shape[1]))
    events = recorder.events
    tasks = task_rows(scenario.tasks.stream, events, float(times[-1]) if len(times) else 0.0)
    legs = leg_rows(events)
    allocations = [e["event"] for e in events if e["type"] == "allocation"]
    telemetry = recorder.telemetry
    return {
        "scenario": scenario.source,
        "scenario_hash": scenario_hash(scenario),
        "seed": scenario.seed,
        "versions": _versions(),
        "duration": duration,
        "wall_time": wall_time,
        "cpu_time": cpu_time,
        "real_time_factor": duration / wall_time if wall_time > 0 else None,
        "tasks": task_totals(tasks) | {"per_task": tasks},
        "legs": legs,
        "predictions": predictions(tasks, legs, allocations),
        "robots": _robots(names, times, states, modes, events),
        "safety": _safety(stack.world.obstacles, names, times, xy, radii, humans, human_radii,
                          recorder.human_names, telemetry.column("max_slack"),
                          controller_wall_safety(scenario)),
        "humans": _humans(stack, times, xy, radii, humans, human_radii),
        "deadlocks": _deadlocks(names, times, xy, modes, humans, recorder.human_names),
        "allocations": _allocations(allocations),
        "planner_failures": int(max((e["total"] for e in events
                                     if e["type"] == "planner_failure"), default=0)),
        "controller_failures": int(telemetry.column("failures").sum()),
        "physics_contacts": stack.contacts.summary() if stack.contacts is not None else None,
        "disturbances": _disturbances(scenario.disturbances, names, times, xy, radii, events),
        "lifts": _lifts([e for e in events if e["type"] == "lift"]),
        "back_offs": _back_offs([e for e in events if e["type"] == "back_off"]),
        "communication": communication_metrics(recorder, 1.0 / scenario.rates.logging),
    }


def _back_offs(events: list[dict]) -> dict:
    """The deadlock watchdog's interventions: how many, and per robot ordered aside."""
    return {"count": len(events),
            "robots": dict(sorted(Counter(e["robot"] for e in events).items())),
            "releases": sum(1 for e in events if e.get("releases"))}


def _lifts(events: list[dict]) -> dict:
    """Rides and waits per lift from the recorder's ``lift`` events."""
    lifts, asked = {}, {}
    for event in events:
        entry = lifts.setdefault(event["lift"], {"rides": 0, "waits": []})
        if event["kind"] == "request":
            asked[event["robot"]] = event["at"]
        elif event["kind"] == "board" and event["robot"] in asked:
            entry["waits"].append(event["at"] - asked.pop(event["robot"]))
        elif event["kind"] == "arrive":
            entry["rides"] += 1
    return {name: {"rides": entry["rides"],
                   "mean_wait": float(np.mean(entry["waits"])) if entry["waits"] else None,
                   "max_wait": float(max(entry["waits"])) if entry["waits"] else None}
            for name, entry in lifts.items()}


def _robots(names, times, states, modes, events) -> dict:
    """Per-robot distance and time split; a sample's mode holds until the next sample."""
    weights = _weights(times)
    steps = np.linalg.norm(np.diff(states[..., :2], axis=0), axis=-1)
    steps[steps > RELOCATION_STEP] = 0.0  # moved by a lift ride, not driven
    robots = {}
    for k, name in enumerate(names):
        mode = modes[:, k]
        robots[name] = {
            "distance": float(steps[:, k].sum()),
            "busy_time": float(weights[(mode != RobotMode.IDLE)
                                       & (mode != RobotMode.QUEUE)].sum()),
            "queue_time": float(weights[mode == RobotMode.QUEUE].sum()),
            "idle_time": float(weights[mode == RobotMode.IDLE].sum()),
            "stops_completed": sum(e["type"] == "arrival" and e["robot"] == name
                                   for e in events),
            "planner_failures": sum(e["type"] == "planner_failure" and name in e["robots"]
                                    for e in events),
            "final_pose": [float(v) for v in states[-1, k, :3]] if len(states) else None,
        }
    return robots


def controller_wall_safety(scenario) -> float:
    """The wall safety distance (m, robot centre to wall) of the scenario's controller: its
    params' ``safety_distances.wall``, or ``DEFAULT_WALL_SAFETY`` for a controller without
    one."""
    params = resolve_block(scenario, "controller")[1]
    distances = getattr(params, "safety_distances", None)
    return float(getattr(distances, "wall", DEFAULT_WALL_SAFETY))


def _safety(obstacles, names, times, xy, radii, humans, human_radii, human_names,
            slack, wall_safety) -> dict:
    """The ``safety`` figures; ``slack`` (T,) the largest CBF slack at each sample."""
    gaps = clearances(obstacles, xy, radii, humans, human_radii)
    result = {}
    for kind, values, who in (
        ("robot_robot", gaps.robot_robot,
         lambda k: [names[i] for i in gaps.pairs[k]]),
        ("robot_wall", gaps.robot_wall, lambda k: [names[k]]),
        ("robot_human", gaps.robot_human.reshape(len(times), -1),
         lambda k: [names[k // len(human_names)], human_names[k % len(human_names)]]),
    ):
        finite = np.where(np.isnan(values), np.inf, values)
        if finite.size and np.isfinite(finite).any():
            s, k = np.unravel_index(np.argmin(finite), finite.shape)
            result |= {f"min_{kind}": float(finite[s, k]), f"min_{kind}_time": float(times[s]),
                       f"min_{kind}_between": who(k)}
        else:
            result |= {f"min_{kind}": None, f"min_{kind}_time": None,
                       f"min_{kind}_between": None}
        with np.errstate(invalid="ignore"):
            result[f"{kind}_contacts"] = int(_onsets(values < 0).sum())
    close = 0.5 * wall_safety
    result["robot_wall_close_distance"] = close
    result["robot_wall_close_time"] = float(
        (_weights(times)[:, None] * (gaps.robot_wall < close)).sum())
    result["max_cbf_slack"] = float(slack.max()) if len(slack) else 0.0
    result["cbf_slack_time"] = float(_weights(times)[slack > SLACK_TOLERANCE].sum())
    return result


def _weights(times: np.ndarray) -> np.ndarray:
    """How long each sample's state holds: until the next sample (the last: 0), s."""
    return np.append(np.diff(times), 0.0)


def _onsets(flags: np.ndarray) -> np.ndarray:
    """Per column, how many times ``flags`` (T, K) turns true (true at the first sample
    counts)."""
    before = np.vstack([np.zeros((1,) + flags.shape[1:], bool), flags[:-1]])
    return (flags & ~before).sum(axis=0)


def _humans(stack, times, xy, radii, humans, human_radii) -> dict | None:
    if stack.humans is None or humans.shape[1] == 0:
        return None
    people = getattr(stack.humans, "people", None)  # a swapped-in block may not say
    waypoints = None if people is None else [p.waypoints for p in people]
    metrics = human_metrics(times, xy, humans, radii, human_radii, human_waypoints=waypoints)
    return {key: (None if not np.isfinite(value) else value)
            for key, value in dataclasses.asdict(metrics).items()}


def _allocations(events: list[dict]) -> dict:
    return {
        "count": len(events),
        "statuses": dict(Counter(e["status"] for e in events if "status" in e)),
        "predicted_late": sorted({t for e in events for t in e.get("late_tasks", ())}),
        "conflicts": sorted({t for e in events for t in e.get("conflict", ())}),
        "solve_time": float(sum(e.get("solve_time", 0.0) for e in events)),
    }


def _disturbances(config, names, times, xy, radii, events) -> list[dict]:
    detours = [e for e in events if e["type"] == "detour"]
    allocations = [e["event"] for e in events if e["type"] == "allocation"]
    result = []
    for blockage in config.blockages:
        caused = [e for e in detours if blockage.name in e["blockages"]]
        result.append({
            "kind": "blockage", "name": blockage.name, "box": list(blockage.box),
            "start": blockage.start, "end": blockage.end,
            "robots_rerouted": sorted({e["robot"] for e in caused if e["found"]}),
            "robots_waited": sorted({e["robot"] for e in caused if not e["found"]}),
            "detours": len(caused)})
    for breakdown in config.breakdowns:
        removal = next((a for a in allocations if breakdown.robot in a.get("removed", ())
                        and a["time"] >= breakdown.start), None)
        result.append({
            "kind": "breakdown", "robot": breakdown.robot, "start": breakdown.start,
            "end": breakdown.end, "removed_at": removal and removal["time"],
            "tasks_reassigned": list(removal["reassigned"]) if removal else [],
            "tasks_failed": list(removal["lost_tasks"]) if removal else []})
    for outage in config.outages:
        k = names.index(outage.robot)
        during = (times >= outage.start) & (times < (np.inf if outage.end is None
                                                     else outage.end))
        gaps = (np.linalg.norm(xy[during] - xy[during, k:k + 1], axis=-1)
                - radii[k] - radii)[:, np.arange(len(names)) != k]
        result.append({
            "kind": "outage", "robot": outage.robot, "start": outage.start, "end": outage.end,
            "min_robot_clearance": float(gaps.min()) if gaps.size else None})
    return result


def _deadlocks(names, times, xy, modes, humans, human_names) -> dict:
    found = find_deadlocks(times, xy, modes == RobotMode.DRIVE, names, humans, human_names,
                           waiting=modes == RobotMode.QUEUE)
    end = float(times[-1]) if len(times) else 0.0
    return {
        "count": len(found),
        "stuck_time": STUCK_TIME,
        "progress_distance": PROGRESS_DISTANCE,
        "neighbour_range": NEIGHBOUR_RANGE,
        "episodes": [dataclasses.asdict(d) | {"duration": d.duration(end)} for d in found],
    }
