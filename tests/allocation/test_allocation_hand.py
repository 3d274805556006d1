"""Hand-worked allocation instances with known answers, for every allocator.

Locations 0..6 lie on a line 10 s apart; every pickup or drop-off takes 1 s.
"""

import numpy as np
import pytest

from mrta_drake.allocation import (
    FEASIBLE,
    INFEASIBLE,
    UNKNOWN,
    Action,
    AllocationProblem,
    GreedyAllocator,
    GreedyAllocatorParams,
    RobotStart,
    RobotStatus,
    SmtAllocator,
    SmtAllocatorParams,
    Task,
    committed_start,
    verify_allocation,
)
from mrta_drake.payloads import DROPOFF, PICKUP

TRAVEL = 10 * np.abs(np.subtract.outer(np.arange(7), np.arange(7)))

ALLOCATORS = {
    "smt": SmtAllocator(),
    "smt_pure": SmtAllocator(SmtAllocatorParams(greedy_start=False)),
    "greedy": GreedyAllocator(),
}


def solve(name, problem):
    allocation = ALLOCATORS[name].allocate(problem)
    assert verify_allocation(problem, allocation) == ()
    return allocation


def tasks_of(allocation):
    return [sorted({action.task for action in route}) for route in allocation.routes]


@pytest.mark.parametrize("name", ALLOCATORS)
def test_deadline_shorter_than_shortest_route(name):
    # From 0 to the pickup at 3 and back: 30 + 1 + 30 + 1 = 62 s > 50 s.
    problem = AllocationProblem(TRAVEL, (RobotStart("a", 0),), (Task(0, 3, 0, 50.0),))
    allocation = solve(name, problem)
    assert allocation.late_tasks == (0,)
    assert allocation.drop_times() == {0: 62.0}  # served as soon as possible
    if name == "greedy":
        assert allocation.status == UNKNOWN
    else:
        assert allocation.status == INFEASIBLE
        assert allocation.conflict == (0,)
        assert not allocation.optimal  # appended after the search (defer_hopeless)
        exact = SmtAllocator(SmtAllocatorParams(defer_hopeless=False)).allocate(problem)
        assert exact.optimal and exact.routes == allocation.routes


@pytest.mark.parametrize("name", ALLOCATORS)
def test_unique_feasible_assignment(name):
    # Only "b" (at 3) reaches task 0 in time (12 s); only "a" (at 0) reaches task 1 (12 s).
    robots = (RobotStart("a", 0), RobotStart("b", 3))
    tasks = (Task(0, 3, 2, 25.0), Task(1, 0, 1, 15.0))
    allocation = solve(name, AllocationProblem(TRAVEL, robots, tasks))
    assert allocation.status == FEASIBLE
    assert tasks_of(allocation) == [[1], [0]]
    assert allocation.drop_times() == {0: 12.0, 1: 12.0}


@pytest.mark.parametrize("name", ALLOCATORS)
@pytest.mark.parametrize("capacity", [1, 2])
def test_capacity_binds(name, capacity):
    # Two items from 1 to 3, due at 35 s: both fit only if carried together (12, 34 s).
    tasks = (Task(0, 1, 3, 35.0), Task(1, 1, 3, 35.0))
    problem = AllocationProblem(TRAVEL, (RobotStart("a", 0, capacity=capacity),), tasks)
    allocation = solve(name, problem)
    if capacity == 2:
        assert allocation.status == FEASIBLE
        assert [a.kind for a in allocation.routes[0]] == [PICKUP, PICKUP, DROPOFF, DROPOFF]
    else:
        assert len(allocation.late_tasks) == 1  # 11, 32 s on time, then 53, 74 s late
        assert sorted(allocation.drop_times().values()) == [32.0, 74.0]
        if name != "greedy":
            assert allocation.status == INFEASIBLE
            assert allocation.conflict == (0, 1)


def replanning_problem():
    """Batch 2 arrives at 20 s. Robot "a" (at 1, free) still has task 0 (5 -> 4, due 90 s)
    planned but not picked up; "b" (at 6) is free from 30 s. New task 1 (1 -> 0, due 40 s)
    can only be done by "a", and then only "b" can still do task 0 in time."""
    robots = (
        RobotStart("a", 1, 20.0, planned=(Action(0, PICKUP), Action(0, DROPOFF))),
        RobotStart("b", 6, 30.0),
    )
    tasks = (Task(0, 5, 4, 90.0, release=0.0), Task(1, 1, 0, 40.0, release=20.0))
    return AllocationProblem(TRAVEL, robots, tasks)


@pytest.mark.parametrize("name", ALLOCATORS)
def test_second_batch_moves_a_task_not_yet_picked_up(name):
    problem = replanning_problem()
    allocation = solve(name, problem)
    assert allocation.status == FEASIBLE
    assert tasks_of(allocation) == [[1], [0]]
    assert allocation.drop_times() == {0: 52.0, 1: 32.0}


@pytest.mark.parametrize(
    "allocator",
    [SmtAllocator(SmtAllocatorParams(append_only=True)),
     GreedyAllocator(GreedyAllocatorParams(append_only=True))],
)
def test_append_only_keeps_the_old_plan_and_misses_the_new_deadline(allocator):
    problem = replanning_problem()
    allocation = allocator.allocate(problem)
    assert verify_allocation(problem, allocation, keep_planned=True) == ()
    assert allocation.routes[0][:2] == (Action(0, PICKUP), Action(0, DROPOFF))
    assert allocation.late_tasks == (1,)
    if isinstance(allocator, SmtAllocator):
        assert allocation.status == INFEASIBLE
        assert allocation.conflict == (1,)


@pytest.mark.parametrize("name", ALLOCATORS)
@pytest.mark.parametrize("finished_at, feasible", [(20.0, True), (50.0, False)])
def test_measured_delay_makes_a_new_task_infeasible(name, finished_at, feasible):
    # "a" finished its pickup at 2 at ``finished_at`` s (planned: 20 s) and drives to drop
    # task 0 at 3; new task 1 (3 -> 4, due 70 s) arrives at 40 s.
    released = {0: Task(0, 2, 3, 300.0), 1: Task(1, 3, 4, 70.0, release=40.0)}
    status = RobotStatus("a", 2, finished_at, carrying=(0,), current=Action(0, DROPOFF))
    start = committed_start(status, 40.0, released, TRAVEL, 1.0)
    assert start.ready_time == max(40.0, finished_at + 11.0)
    assert (start.location, start.carrying) == (3, ())
    problem = AllocationProblem(TRAVEL, (start,), (released[1],))
    allocation = solve(name, problem)
    if feasible:
        assert allocation.status == FEASIBLE
        assert allocation.drop_times() == {1: 52.0}
    else:
        assert allocation.late_tasks == (1,)
        assert allocation.drop_times() == {1: 73.0}  # 61 s ready, 62 pickup, 73 drop-off
        if name != "greedy":
            assert (allocation.status, allocation.conflict) == (INFEASIBLE, (1,))


@pytest.mark.parametrize("name", ALLOCATORS)
def test_carried_items_are_dropped_by_their_carrier(name):
    robots = (RobotStart("a", 0, carrying=(0, 1)), RobotStart("b", 3))
    tasks = (Task(0, 0, 2, 100.0), Task(1, 0, 4, 100.0), Task(2, 3, 4, 100.0))
    allocation = solve(name, AllocationProblem(TRAVEL, robots, tasks))
    assert allocation.status == FEASIBLE
    assert set(tasks_of(allocation)[0]) >= {0, 1}


def test_no_tasks():
    problem = AllocationProblem(TRAVEL, (RobotStart("a", 0),), ())
    for allocator in ALLOCATORS.values():
        allocation = allocator.allocate(problem)
        assert allocation.status == FEASIBLE and allocation.routes == ((),)


@pytest.mark.parametrize("objective, value", [("makespan", 22.0), ("lateness", 34.0 - 200.0)])
def test_objectives(objective, value):
    # Two robots at 0, tasks 0 -> 1 and 0 -> 2: done apart, the drop-offs are at 12 and 22 s;
    # by one robot at best at 13 and 24 s.
    robots = (RobotStart("a", 0), RobotStart("b", 0))
    tasks = (Task(0, 0, 1, 100.0), Task(1, 0, 2, 100.0))
    problem = AllocationProblem(TRAVEL, robots, tasks)
    params = SmtAllocatorParams(objective=objective, objective_gap=0.5)
    allocation = SmtAllocator(params).allocate(problem)
    assert verify_allocation(problem, allocation) == ()
    assert allocation.optimal
    if objective == "makespan":
        assert allocation.makespan() == value
    else:
        assert allocation.total_lateness(problem) == value


def test_time_limit_returns_the_best_answer_so_far():
    robots = (RobotStart("a", 0), RobotStart("b", 6))
    tasks = tuple(Task(i, i % 7, (3 * i + 1) % 7, 400.0) for i in range(8))
    problem = AllocationProblem(TRAVEL, robots, tasks)
    params = SmtAllocatorParams(greedy_start=False, time_limit=1e-6)
    allocation = SmtAllocator(params).allocate(problem)
    assert verify_allocation(problem, allocation) == ()
    assert not allocation.optimal and "time limit" in allocation.note
