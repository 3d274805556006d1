"""Hopeless tasks (no robot can drop them off by their deadline even alone) are detected
soundly, against exhaustive search, and the SMT allocator appends them after an exact answer
for the others."""

import numpy as np
import pytest

from mrta_drake.allocation import (
    INFEASIBLE,
    Action,
    AllocationProblem,
    RobotStart,
    SmtAllocator,
    SmtAllocatorParams,
    Task,
    verify_allocation,
)
from mrta_drake.allocation.hopeless import hopeless_tasks, without_tasks
from mrta_drake.payloads import DROPOFF, PICKUP
from tests.allocation.brute_force import brute_force
from tests.allocation.test_allocation_random import SEEDS, random_problem


@pytest.mark.parametrize("seed", SEEDS)
def test_a_hopeless_task_is_late_even_alone(seed):
    """Exhaustive search on the problem with only that task open cannot put it on time."""
    problem = random_problem(seed)
    open_tasks = {task.id for task in problem.tasks if problem.carrier(task.id) is None}
    for t in hopeless_tasks(problem):
        alone = without_tasks(problem, open_tasks - {t})
        fewer = without_tasks(alone, {t}) if t in open_tasks else None
        most = brute_force(alone).most_on_time
        if fewer is None:  # on board: its robot's start alone makes it late
            robot = problem.robots[problem.carrier(t)]
            arrive = (robot.ready_time + problem.travel[robot.location, problem.task(t).dropoff]
                      + problem.service_time)
            assert arrive > problem.task(t).deadline
        else:
            assert most == brute_force(fewer).most_on_time


def test_hopeless_detection_finds_the_late_stream():
    """Ten tasks on a line, two robots at 0; the ones due before any robot can get there
    are hopeless, exactly those."""
    travel = np.abs(np.subtract.outer(np.arange(6), np.arange(6))) * 10
    robots = (RobotStart("a", 0, 0.0, 2), RobotStart("b", 0, 5.0, 2))
    tasks = tuple(Task(i, 1 + i % 5, 0, deadline=12.0 + 9 * i) for i in range(10))
    problem = AllocationProblem(travel, robots, tasks)
    # earliest drop-off of task i: 2 * (10 * (1 + i % 5) + 1)
    expected = tuple(i for i in range(10) if 2 * (10 * (1 + i % 5) + 1) > 12.0 + 9 * i)
    assert hopeless_tasks(problem) == expected
    assert expected  # the instance has some


def test_hopeless_tasks_go_last_and_leave_the_others_exact():
    travel = np.abs(np.subtract.outer(np.arange(6), np.arange(6))) * 10
    robots = (RobotStart("a", 0, 0.0, 1), RobotStart("b", 0, 0.0, 1))
    tasks = (Task(0, 1, 0, 30.0), Task(1, 5, 0, 20.0), Task(2, 2, 0, 60.0),
             Task(3, 4, 0, 10.0))
    problem = AllocationProblem(travel, robots, tasks)
    assert hopeless_tasks(problem) == (1, 3)
    allocation = SmtAllocator().allocate(problem)
    assert verify_allocation(problem, allocation) == ()
    assert allocation.status == INFEASIBLE
    assert set(allocation.late_tasks) >= {1, 3}
    for route in allocation.routes:
        kinds = [action.task in (1, 3) for action in route]
        assert kinds == sorted(kinds)  # hopeless ones only at the end
    rest = SmtAllocator().allocate(without_tasks(problem, {1, 3}))
    hopeful = {t: time for t, time in allocation.drop_times().items() if t not in (1, 3)}
    assert hopeful == rest.drop_times()
    assert "cannot be on time" in allocation.note


def test_a_hopeless_task_in_a_previous_plan_is_appended_too():
    """The robots' ``planned`` hints may name a task that has become hopeless."""
    travel = np.abs(np.subtract.outer(np.arange(6), np.arange(6))) * 10
    tasks = (Task(0, 1, 0, 30.0), Task(1, 5, 0, 20.0))
    planned = (Action(1, PICKUP), Action(1, DROPOFF), Action(0, PICKUP), Action(0, DROPOFF))
    robots = (RobotStart("a", 0, 0.0, 1, planned=planned), RobotStart("b", 0, 0.0, 1))
    problem = AllocationProblem(travel, robots, tasks)
    for append_only in (False, True):
        allocation = SmtAllocator(SmtAllocatorParams(append_only=append_only)).allocate(problem)
        assert verify_allocation(problem, allocation) == ()
        assert 1 in allocation.late_tasks
