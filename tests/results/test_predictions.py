"""The summary's predictions section: errors, promises kept and broken, re-plans."""

import pytest

from mrta_drake.results.predictions import error_stats, predictions


def task(task_id, predicted, actual, met):
    return {"id": task_id, "predicted_dropoff": predicted, "actual_dropoff": actual,
            "deadline_met": met}


TASKS = [task(0, 40.0, 50.0, True), task(1, 60.0, 58.0, False), task(2, 70.0, None, False),
         task(3, 90.0, 120.0, False)]
LEGS = [{"actual": 12.0, "predicted": 10.0}, {"actual": 9.0, "predicted": None}]
ALLOCATIONS = [
    {"kind": "AllocationEvent", "time": 0.0, "predicted": [[0, 40.0], [1, 50.0]],
     "late_tasks": [1]},
    {"kind": "ReplanEvent", "time": 20.0, "predicted": [[1, 60.0], [2, 70.0]],
     "late_tasks": [], "reason": "drift: task 1 (+10 s)"},
    {"kind": "AllocationEvent", "time": 30.0, "predicted": [[3, 90.0]], "late_tasks": [3]},
]


def test_errors_promises_and_replans():
    section = predictions(TASKS, LEGS, ALLOCATIONS)
    assert section["dropoff_error"] == {"count": 3, "median_abs": 10.0,
                                        "p90_abs": pytest.approx(26.0), "bias": 38 / 3,
                                        "max": 30.0}
    assert section["leg_error"]["count"] == 1 and section["leg_error"]["bias"] == 2.0
    # Task 1 was late at 0 s but promised by the re-plan; task 3 never was.
    assert section["promised"] == 3
    assert section["broken_promises"] == [1, 2]
    assert section["unpromised"] == [3]
    assert section["replans"] == {"count": 1, "reasons": {"drift": 1},
                                  "events": [{"time": 20.0, "reason": "drift: task 1 (+10 s)"}]}
    assert section["drift"] == [[50.0, 10.0], [58.0, -2.0], [120.0, 30.0]]


def test_no_errors_give_none():
    assert error_stats([]) == {"count": 0, "median_abs": None, "p90_abs": None, "bias": None,
                               "max": None}
