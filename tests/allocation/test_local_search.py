"""Local search: never worse than its start, valid, deterministic, and it does improve."""

from dataclasses import replace

import numpy as np
import pytest

from mrta_drake.allocation import (
    INFEASIBLE,
    Action,
    Allocation,
    AllocationProblem,
    GreedyAllocator,
    RobotStart,
    Task,
    verify_allocation,
)
from mrta_drake.allocation.local_search import (
    LocalSearchParams,
    improve,
    improve_keeping_verdict,
)
from mrta_drake.errors import InputError
from mrta_drake.payloads import DROPOFF, PICKUP
from tests.allocation.brute_force import brute_force
from tests.allocation.test_allocation_random import SEEDS, random_problem
from tests.allocation.tight_instances import tight_problem


@pytest.mark.parametrize("seed", SEEDS)
def test_never_worse_than_its_start_and_valid(seed):
    problem = random_problem(seed)
    greedy = GreedyAllocator().allocate(problem)
    improved = improve(problem, greedy)
    assert verify_allocation(problem, improved) == ()
    assert improved.rank(problem) <= greedy.rank(problem)
    best = brute_force(problem)
    assert len(problem.tasks) - len(improved.late_tasks) <= best.most_on_time


def test_improves_greedy_on_tight_instances_deterministically():
    gains = 0
    for seed in range(6):
        problem = tight_problem(seed, num_tasks=14, num_robots=3)
        greedy = GreedyAllocator().allocate(problem)
        improved = improve(problem, greedy)
        assert verify_allocation(problem, improved) == ()
        assert improve(problem, greedy) == improved
        assert improved.rank(problem) <= greedy.rank(problem)
        gains += improved.rank(problem) < greedy.rank(problem)
    assert gains >= 3


def test_a_small_evaluation_budget_stops_early_the_same_way_every_time():
    problem = tight_problem(0, 14, 3)
    greedy = GreedyAllocator().allocate(problem)
    params = LocalSearchParams(max_evaluations=300)
    cut = improve(problem, greedy, params)
    assert verify_allocation(problem, cut) == ()
    assert improve(problem, greedy, params) == cut
    assert greedy.rank(problem) >= cut.rank(problem) > improve(problem, greedy).rank(problem)


@pytest.mark.parametrize("field, value", [("max_rounds", -1), ("max_evaluations", 1.5),
                                          ("max_evaluations", True)])
def test_bad_params_are_one_line_naming_the_field(field, value):
    with pytest.raises(InputError) as error:
        LocalSearchParams(**{field: value})
    assert str(error.value).startswith(f"{field}: ") and "\n" not in str(error.value)


def test_no_rounds_keeps_the_start():
    problem = tight_problem(0, num_tasks=14, num_robots=3)
    greedy = GreedyAllocator().allocate(problem)
    assert improve(problem, greedy, LocalSearchParams(max_rounds=0)) is greedy


def test_improving_keeps_the_allocators_verdict():
    problem = tight_problem(0, num_tasks=14, num_robots=3)
    greedy = GreedyAllocator().allocate(problem)
    proven = replace(greedy, status=INFEASIBLE, conflict=(3, 5), note="proven", work=7)
    kept = improve_keeping_verdict(problem, proven)
    improved = improve(problem, greedy)
    assert improved.late_tasks  # still late: the verdict stands
    assert (kept.routes, kept.times, kept.late_tasks) == (
        improved.routes, improved.times, improved.late_tasks)
    assert (kept.status, kept.conflict, kept.note, kept.work) == (INFEASIBLE, (3, 5), "proven", 7)
    assert kept.rank(problem) < proven.rank(problem)


def test_a_task_written_off_goes_after_the_one_that_can_be_on_time():
    """One robot at 0 on a line of locations 10 s apart: task 0 (1 -> 2) is due long before
    any robot can drop it off, task 1 (3 -> 4) has room. Least tardiness does task 0 first
    (17 s late, task 1 dropped at 44 s); written off after 5 s, task 1 goes first (dropped at
    42 s) and task 0 after it, 79 s late."""
    travel = 10 * np.abs(np.subtract.outer(np.arange(5), np.arange(5)))
    problem = AllocationProblem(travel, (RobotStart("r", 0),),
                                (Task(0, 1, 2, deadline=5.0), Task(1, 3, 4, deadline=200.0)))
    start = Allocation.of(problem, [[Action(1, PICKUP), Action(1, DROPOFF),
                                     Action(0, PICKUP), Action(0, DROPOFF)]])
    earliest = improve(problem, start)
    assert earliest.drop_times() == {0: 22.0, 1: 44.0}
    written_off = improve(problem, earliest, LocalSearchParams(write_off=5.0))
    assert verify_allocation(problem, written_off) == ()
    assert written_off.drop_times() == {1: 42.0, 0: 84.0}
    assert written_off.rank(problem, 5.0) == (1, 5.0, 0.0, 42.0, 84.0)
    assert written_off.rank(problem) == (1, 79.0, 0.0, 126.0, 0.0)
    kept = improve_keeping_verdict(problem, replace(earliest, status=INFEASIBLE, optimal=True),
                                   LocalSearchParams(write_off=5.0))
    assert (kept.routes, kept.status, kept.optimal) == (written_off.routes, INFEASIBLE, False)


@pytest.mark.parametrize("name", ["write_off", "slack"])
def test_write_off_and_slack_must_not_be_negative(name):
    with pytest.raises(InputError) as error:
        LocalSearchParams(**{name: -1.0})
    assert str(error.value).startswith(f"{name}: ")


@pytest.mark.parametrize("slack, drops", [(0.0, {0: 12.0, 1: 54.0}),
                                          (5.0, {0: 12.0, 1: 54.0}),
                                          (10.0, {1: 32.0, 0: 74.0})])
def test_a_safety_slack_gives_the_tightest_promise_more_room(slack, drops):
    """One robot at 0 carrying one item at a time, locations on a line 10 s apart: task 0
    (0 -> 1, due at 100 s) first drops both off soonest (12 s and 54 s) but leaves task 1
    (0 -> 3, due at 60 s) 6 s of room; task 1 first gives it 28 s and task 0 still 26 s.
    With a slack above 6 s the search takes the second."""
    travel = 10 * np.abs(np.subtract.outer(np.arange(4), np.arange(4)))
    problem = AllocationProblem(travel, (RobotStart("r", 0, capacity=1),),
                                (Task(0, 0, 1, deadline=100.0), Task(1, 0, 3, deadline=60.0)))
    start = Allocation.of(problem, [[Action(0, PICKUP), Action(0, DROPOFF),
                                     Action(1, PICKUP), Action(1, DROPOFF)]])
    improved = improve(problem, start, LocalSearchParams(slack=slack))
    assert improved.drop_times() == drops
    assert start.rank(problem, slack=slack)[2] == max(0.0, slack - 6.0)
    assert improved.rank(problem, slack=slack)[:3] == (0, 0.0, 0.0)
