"""Small random problems: the SMT allocator agrees with exhaustive search, and every answer
of every allocator passes the independent checker."""

import itertools

import numpy as np
import pytest

from mrta_drake.allocation import (
    FEASIBLE,
    INFEASIBLE,
    AllocationProblem,
    GreedyAllocator,
    RobotStart,
    SmtAllocator,
    SmtAllocatorParams,
    Task,
    verify_allocation,
)
from tests.allocation.brute_force import assert_optimum, brute_force

SEEDS = range(120)


def random_problem(seed: int) -> AllocationProblem:
    """<= 3 robots, <= 4 tasks on 5 locations with asymmetric integer travel times; some
    robots start late or carry an item, some tasks are released late."""
    rng = np.random.default_rng(seed)
    num_locations = 5
    travel = rng.integers(1, 30, size=(num_locations, num_locations))
    np.fill_diagonal(travel, 0)
    num_tasks = int(rng.integers(1, 5))
    tasks = []
    for i in range(num_tasks):
        pickup, dropoff = (int(x) for x in rng.choice(num_locations, 2, replace=False))
        release = float(rng.choice([0, 0, rng.integers(1, 30)]))
        tasks.append(Task(i, pickup, dropoff, release + float(rng.integers(20, 120)), release))
    robots, carried = [], iter(range(num_tasks)) if rng.random() < 0.3 else iter(())
    for r in range(int(rng.integers(1, 4))):
        capacity = int(rng.integers(1, 3))
        carrying = tuple(t for t in [next(carried, None)] if t is not None)
        ready = float(rng.choice([0, rng.integers(0, 15)]))
        ready = max([ready, *(tasks[t].release for t in carrying)])
        robots.append(RobotStart(f"r{r}", int(rng.integers(num_locations)), ready, capacity,
                                 carrying))
    return AllocationProblem(travel, tuple(robots), tuple(tasks))


def check(problem, allocation):
    assert verify_allocation(problem, allocation) == ()
    return allocation


@pytest.mark.parametrize("seed", SEEDS)
def test_smt_agrees_with_exhaustive_search(seed):
    """Most tasks on time over the whole problem; least tardiness over the whole problem, or,
    deferring hopeless tasks, over the tasks that can still be on time (the hopeless open ones
    are appended after them)."""
    problem = random_problem(seed)
    best = brute_force(problem)
    for greedy_start, defer in itertools.product((True, False), (True, False)):
        params = SmtAllocatorParams(greedy_start=greedy_start, objective_gap=0.5,
                                    defer_hopeless=defer)
        allocation = check(problem, SmtAllocator(params).allocate(problem))
        assert allocation.status == (FEASIBLE if best.feasible else INFEASIBLE)
        assert_optimum(problem, allocation, best, defer)
        if not best.feasible:
            assert allocation.conflict


@pytest.mark.parametrize("seed", SEEDS)
def test_smt_objectives_are_optimal(seed):
    problem = random_problem(seed)
    best = brute_force(problem)
    if not best.feasible:
        pytest.skip("objectives apply when every task can be on time")
    params = SmtAllocatorParams(objective="makespan", objective_gap=0.5)
    allocation = check(problem, SmtAllocator(params).allocate(problem))
    assert allocation.makespan() == pytest.approx(best.least_makespan)
    params = SmtAllocatorParams(objective="lateness", objective_gap=0.5)
    allocation = check(problem, SmtAllocator(params).allocate(problem))
    assert sum(allocation.drop_times().values()) == pytest.approx(best.least_total_drop_time)


@pytest.mark.parametrize("seed", SEEDS)
def test_greedy_answers_are_valid(seed):
    problem = random_problem(seed)
    allocation = check(problem, GreedyAllocator().allocate(problem))
    assert len(problem.tasks) - len(allocation.late_tasks) <= brute_force(problem).most_on_time
