"""The independent checker rejects broken allocations."""

import dataclasses

import numpy as np
import pytest

from mrta_drake.allocation import (
    FEASIBLE,
    INFEASIBLE,
    Action,
    Allocation,
    AllocationProblem,
    RobotStart,
    Task,
    verify_allocation,
)
from mrta_drake.payloads import DROPOFF, PICKUP

TRAVEL = 10 * np.abs(np.subtract.outer(np.arange(4), np.arange(4)))
PROBLEM = AllocationProblem(
    TRAVEL,
    (RobotStart("a", 0, capacity=1), RobotStart("b", 3, carrying=(2,))),
    (Task(0, 1, 2, 100.0), Task(1, 1, 3, 100.0), Task(2, 0, 2, 100.0)),
)
GOOD = Allocation.of(PROBLEM, (
    (Action(0, PICKUP), Action(0, DROPOFF), Action(1, PICKUP), Action(1, DROPOFF)),
    (Action(2, DROPOFF),),
))


def broken(routes=None, **changes):
    allocation = Allocation.of(PROBLEM, routes) if routes is not None else GOOD
    return dataclasses.replace(allocation, **changes)


def test_a_valid_allocation_passes():
    assert GOOD.status == FEASIBLE
    assert verify_allocation(PROBLEM, GOOD) == ()


@pytest.mark.parametrize("allocation, complaint", [
    (broken(((Action(0, PICKUP), Action(0, DROPOFF)), (Action(2, DROPOFF),))),
     "task 1 is never dropped off"),
    (broken(((Action(0, DROPOFF), Action(0, PICKUP), Action(1, PICKUP), Action(1, DROPOFF)),
             (Action(2, DROPOFF),))), "dropped off but not on board"),
    (broken(((Action(0, PICKUP), Action(1, PICKUP), Action(0, DROPOFF), Action(1, DROPOFF)),
             (Action(2, DROPOFF),))), "capacity 1"),
    (broken(((Action(0, PICKUP), Action(0, DROPOFF), Action(1, PICKUP), Action(1, DROPOFF),
              Action(2, DROPOFF)), ())), "dropped off but not on board"),
    (broken(((Action(0, PICKUP), Action(0, DROPOFF)),
             (Action(2, DROPOFF), Action(1, PICKUP), Action(1, DROPOFF), Action(1, DROPOFF)))),
     "dropped off again"),
    (broken(times=((11.0, 22.0, 33.0, 55.0), (21.0,))), "completes at"),
    (broken(late_tasks=(1,)), "late tasks are []"),
    (broken(status=INFEASIBLE), "status infeasible"),
    (broken(routes=((Action(0, PICKUP), Action(0, DROPOFF), Action(1, PICKUP),
                     Action(1, DROPOFF)),)), "routes"),
])
def test_broken_allocations_are_caught(allocation, complaint):
    violations = verify_allocation(PROBLEM, allocation)
    assert any(complaint in violation for violation in violations), violations


def test_late_tasks_must_be_flagged_and_status_must_agree():
    tight = AllocationProblem(TRAVEL, PROBLEM.robots, (
        Task(0, 1, 2, 20.0), Task(1, 1, 3, 100.0), Task(2, 0, 2, 100.0)))
    honest = Allocation.of(tight, GOOD.routes)
    assert honest.late_tasks == (0,)
    assert verify_allocation(tight, honest) == ()
    violations = verify_allocation(tight, dataclasses.replace(honest, status=FEASIBLE))
    assert any("status feasible" in violation for violation in violations)


def test_keep_planned():
    problem = dataclasses.replace(PROBLEM, robots=(
        RobotStart("a", 0, capacity=1, planned=(Action(1, PICKUP), Action(1, DROPOFF))),
        PROBLEM.robots[1],
    ))
    assert verify_allocation(problem, GOOD) == ()
    assert verify_allocation(problem, GOOD, keep_planned=True) == (
        "a: the planned actions were not kept",)
