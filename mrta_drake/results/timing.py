"""Predicted against actual times of tasks and stops, from a run's recorded events.

Works on the event dicts of ``RunRecorder`` (or the lines of ``events.jsonl``): ``plan``
events carry the allocator's predicted completion time of every planned stop, ``start``
events when a robot began a stop and ``arrival`` events when it completed one (both at
``at``). The prediction used for a stop is the latest one made before it was completed:
plans change as new task batches arrive. Times are simulation seconds.

Tasks are numbered as the task allocator numbers them (``stream_tasks``): in stream order
from 0, batch by batch.
"""

import math

from mrta_drake.allocation.problem import stream_tasks
from mrta_drake.payloads import DROPOFF, PICKUP

ON_TIME = "on_time"  # dropped off by the deadline
LATE = "late"  # dropped off after the deadline
CARRYING = "carrying"  # picked up, not yet dropped off
FAILED = "failed"  # its item was lost with a robot that broke down
ASSIGNED = "assigned"  # in some robot's plan, not yet picked up
UNASSIGNED = "unassigned"  # released but never planned
NOT_RELEASED = "not_released"  # its batch arrives after the end of the run


def task_rows(stream, events, end_time: float) -> list[dict]:
    """One dict per task of ``stream`` (``TaskBatch`` list), in id order: ``id``,
    ``arrival``, ``pickup`` and ``dropoff`` (location ids), ``deadline``, ``robot`` (who
    did it, else who last had it planned), ``assigned_at`` (first plan holding it),
    ``predicted_pickup``/``actual_pickup`` and ``predicted_dropoff``/``actual_dropoff``
    (completion times), ``status``, ``deadline_met`` (None while undecided at
    ``end_time``) and ``lateness`` (drop-off minus deadline; negative = early; None if not
    dropped off). Unknown times are None. A task whose item an allocation event reports
    lost (``lost_tasks``, a robot broke down carrying it) has failed."""
    done, done_by, lost = {}, {}, set()
    for event in events:
        if event["type"] == "arrival" and event.get("task") is not None:
            done[event["task"], event["action"]] = event["at"]
            done_by[event["task"], event["action"]] = event["robot"]
        elif event["type"] == "allocation":
            lost.update(event["event"].get("lost_tasks", ()))
    predicted, planned_robot, assigned_at = {}, {}, {}
    for event in events:
        if event["type"] != "plan":
            continue
        for robot, stops in event["plans"].items():
            for stop in stops:
                task = stop["task"]
                if task is None:
                    continue
                assigned_at.setdefault(task, event["time"])
                what = (task, stop["action"])
                if event["time"] <= done.get(what, math.inf):
                    planned_robot[task] = robot
                    if _number(stop["planned"]) is not None:
                        predicted[what] = _number(stop["planned"])
    rows = []
    for task in (task for batch in stream_tasks(stream) for task in batch):
        task_id, arrival = task.id, task.release
        dropped = done.get((task_id, DROPOFF))
        picked = done.get((task_id, PICKUP))
        lateness = None if dropped is None else dropped - task.deadline
        if dropped is not None:
            status = ON_TIME if lateness <= 0 else LATE
            met = lateness <= 0
        else:
            status = (NOT_RELEASED if arrival > end_time else FAILED if task_id in lost
                      else CARRYING if picked is not None
                      else ASSIGNED if task_id in assigned_at else UNASSIGNED)
            met = False if end_time > task.deadline or status == FAILED else None
        rows.append({
            "id": task_id, "arrival": arrival, "pickup": task.pickup, "dropoff": task.dropoff,
            "deadline": task.deadline,
            "robot": done_by.get((task_id, DROPOFF), done_by.get((task_id, PICKUP),
                                                                  planned_robot.get(task_id))),
            "assigned_at": assigned_at.get(task_id),
            "predicted_pickup": predicted.get((task_id, PICKUP)), "actual_pickup": picked,
            "predicted_dropoff": predicted.get((task_id, DROPOFF)), "actual_dropoff": dropped,
            "status": status, "deadline_met": met, "lateness": lateness,
        })
    return rows


def task_totals(rows: list[dict]) -> dict:
    """Counts over ``task_rows``: ``total``, ``released``, ``assigned`` (ever planned),
    ``completed``, ``on_time``, ``late`` (completed late), ``missed`` (deadline not met,
    done or not), ``failed`` (items lost), ``completed_ids``; over completed tasks
    ``mean_lateness``,
    ``max_lateness`` and ``total_tardiness`` (sum of positive lateness), s (None if none)."""
    done = [r for r in rows if r["actual_dropoff"] is not None]
    lateness = [r["lateness"] for r in done]
    return {
        "total": len(rows),
        "released": sum(r["status"] != NOT_RELEASED for r in rows),
        "assigned": sum(r["assigned_at"] is not None for r in rows),
        "completed": len(done),
        "on_time": sum(r["status"] == ON_TIME for r in rows),
        "late": sum(r["status"] == LATE for r in rows),
        "missed": sum(r["deadline_met"] is False for r in rows),
        "failed": sum(r["status"] == FAILED for r in rows),
        "completed_ids": [r["id"] for r in done],
        "mean_lateness": sum(lateness) / len(lateness) if lateness else None,
        "max_lateness": max(lateness, default=None),
        "total_tardiness": sum(max(0.0, x) for x in lateness) if lateness else None,
    }


def leg_rows(events) -> list[dict]:
    """One dict per completed stop (leg), in completion order: ``robot``, ``key``,
    ``task``, ``action``, ``location``; ``start`` (the robot began the stop) and ``end``
    (completed it), s; ``actual`` = end - start and ``predicted``: the latest plan's
    predicted completion of the stop minus its predicted completion of the stop before it
    (or minus ``start`` for the plan's first stop), s (None without a prediction)."""
    starts = {}
    plans = [e for e in events if e["type"] == "plan"]
    rows = []
    for event in events:
        if event["type"] == "start":
            starts[event["robot"], event["key"]] = event["at"]
        elif event["type"] == "arrival":
            robot, key, end = event["robot"], event["key"], event["at"]
            start = starts.get((robot, key), end)
            rows.append({
                "robot": robot, "key": key, "task": event.get("task"),
                "action": event.get("action"), "location": event["location"],
                "start": start, "end": end, "actual": end - start,
                "predicted": _predicted_leg(plans, robot, key, start, end),
            })
    return rows


def _predicted_leg(plans, robot: str, key: str, start: float, end: float) -> float | None:
    for plan in reversed(plans):
        if plan["time"] > end:
            continue
        stops = plan["plans"].get(robot, ())
        keys = [stop["key"] for stop in stops]
        if key not in keys:
            continue
        k = keys.index(key)
        planned = _number(stops[k]["planned"])
        before = _number(stops[k - 1]["planned"]) if k > 0 else start
        return None if planned is None or before is None else planned - before
    return None


def _number(value) -> float | None:
    """A finite float, or None (for None and NaN, as the events hold them in memory or
    on file)."""
    return None if value is None or not math.isfinite(value) else float(value)
