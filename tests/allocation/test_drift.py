"""find_drift: drop-offs a robot's progress makes late or moves past the margin."""

import numpy as np

from mrta_drake.allocation.drift import DRIFT, LATE, find_drift
from mrta_drake.allocation.problem import Action, AllocationProblem, RobotStart, Task
from mrta_drake.payloads import DROPOFF, PICKUP, RobotPlan, Stop

TRAVEL = 10 * np.abs(np.subtract.outer(np.arange(3), np.arange(3)))


def problem(ready: float, deadline: float) -> AllocationProblem:
    planned = (Action(0, PICKUP), Action(0, DROPOFF))
    robot = RobotStart("a", 0, ready, planned=planned)
    return AllocationProblem(TRAVEL, (robot,), (Task(0, 1, 2, deadline),))


PLAN = RobotPlan("a", (Stop("t0/pickup", 1, PICKUP, 0, 11.0),
                       Stop("t0/dropoff", 2, DROPOFF, 0, 22.0)))


def test_within_the_margin_nothing_drifts():
    assert find_drift(problem(4.0, 100.0), [PLAN], margin=5.0) is None


def test_past_the_margin_the_drop_off_drifts():
    drift = find_drift(problem(6.0, 100.0), [PLAN], margin=5.0)
    assert (drift.kind, drift.tasks, drift.seconds) == (DRIFT, (0,), 6.0)
    assert drift.reason == "drift: task 0 (+6 s)"


def test_a_promise_turned_late_is_late_whatever_the_margin():
    drift = find_drift(problem(2.0, 23.0), [PLAN], margin=5.0)
    assert (drift.kind, drift.tasks) == (LATE, (0,))


def test_a_task_planned_late_is_not_a_new_lateness():
    assert find_drift(problem(2.0, 20.0), [PLAN], margin=5.0) is None
