"""The SMT allocator's budget is z3 work, not time: the same problem and budget give the same
allocation (and the same work) every time, in one process, whatever was solved in between,
also when the budget runs out."""

import dataclasses

import numpy as np
import pytest

from mrta_drake.allocation import (
    INFEASIBLE,
    AllocationProblem,
    RobotStart,
    SmtAllocator,
    SmtAllocatorParams,
    Task,
    verify_allocation,
)
from mrta_drake.allocation.smt_allocator import MAX_BUDGET, best_heuristic
from mrta_drake.errors import InputError
from tests.allocation.tight_instances import tight_problem

TINY_BUDGET = 200_000  # z3 resource units: a fraction of a second


def random_problem(seed: int, num_tasks: int, num_robots: int, latest: float):
    """``num_tasks`` tasks between 12 random points (travel: Manhattan distance at 1 m/s on a
    40 x 40 m floor), all released at 0 and due at a uniform draw from 60 s to ``latest``."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(0.0, 40.0, size=(12, 2))
    travel = np.ceil(np.abs(points[:, None] - points[None]).sum(axis=-1))
    robots = tuple(RobotStart(f"r{r}", int(rng.integers(12))) for r in range(num_robots))
    tasks = tuple(
        Task(i, *(int(x) for x in rng.choice(12, 2, replace=False)),
             float(rng.integers(60, int(latest) + 1)))
        for i in range(num_tasks))
    return AllocationProblem(travel, robots, tasks)


def without_wall_clock(allocation) -> dict:
    return {k: v for k, v in dataclasses.asdict(allocation).items() if k != "solve_time"}


def solve_again_and_again(allocator, problem, other):
    """``problem``'s answer, then again after solving ``other``, then once more."""
    answers = []
    for _ in range(2):
        answers.append(allocator.allocate(problem))
        allocator.allocate(other)
    answers.append(allocator.allocate(problem))
    for answer in answers:
        assert verify_allocation(problem, answer) == ()
    return answers


def test_a_problem_that_exhausts_the_budget_gets_the_same_answer_every_time():
    # 20 tight tasks on 3 robots: the greedy answer has tasks late and z3 neither finds a
    # better one nor proves there is none within the budget.
    problem = random_problem(0, 20, 3, latest=150.0)
    other = random_problem(0, 20, 3, latest=200.0)
    allocator = SmtAllocator(SmtAllocatorParams(budget=TINY_BUDGET))
    first, *again = solve_again_and_again(allocator, problem, other)
    assert first.late_tasks and not first.optimal
    assert "budget ran out" in first.note
    assert first.work >= TINY_BUDGET
    for answer in again:
        assert without_wall_clock(answer) == without_wall_clock(first)


def test_a_budget_exhausted_while_polishing_gets_the_same_answer_every_time():
    # 14 tight tasks on 3 robots: z3 proves the most tasks on time, then the budget runs out
    # in the least-tardiness search, whose answers local search polishes.
    problem = tight_problem(7, 14, 3)
    other = tight_problem(2, 14, 3)
    allocator = SmtAllocator(SmtAllocatorParams(budget=1_000_000))
    first, *again = solve_again_and_again(allocator, problem, other)
    assert first.note.startswith("budget ran out before the fallback was proven best")
    assert first.rank(problem) <= best_heuristic(problem).rank(problem)
    for answer in again:
        assert without_wall_clock(answer) == without_wall_clock(first)


@pytest.mark.parametrize("objective", ["none", "makespan"])
def test_a_problem_solved_within_the_budget_gets_the_same_answer_every_time(objective):
    problem = random_problem(2, 10, 3, latest=400.0)
    other = random_problem(1, 8, 2, latest=300.0)
    params = SmtAllocatorParams(objective=objective, greedy_start=False)
    first, *again = solve_again_and_again(SmtAllocator(params), problem, other)
    assert first.optimal and first.note == "" and 0 < first.work < params.budget
    for answer in again:
        assert without_wall_clock(answer) == without_wall_clock(first)


def test_the_budget_bounds_the_search_for_a_proof():
    # 8 tasks due by 90 s from 2 robots: infeasible, proven with the default budget (4 tasks
    # cannot all be on time); a tiny budget runs out while the encoding is being built.
    problem = random_problem(4, 8, 2, latest=90.0)
    proven = SmtAllocator().allocate(problem)
    assert proven.status == INFEASIBLE and proven.optimal and len(proven.conflict) == 4
    cut = SmtAllocator(SmtAllocatorParams(budget=1000)).allocate(problem)
    assert verify_allocation(problem, cut) == ()
    assert cut.note == "budget ran out while building the encoding" and not cut.optimal
    # The heuristic answer (greedy, then local search) is as good here, but not proven.
    assert not cut.conflict and len(cut.late_tasks) >= len(proven.late_tasks)


@pytest.mark.parametrize("field, value, words", [
    ("budget", 0, "from 1 to"),
    ("budget", MAX_BUDGET + 1, "from 1 to"),
    ("budget", 1.5, "whole number"),
    ("budget", True, "whole number"),
    ("time_limit", 0.0, "> 0 s"),
])
def test_bad_limits_are_one_line_naming_the_field(field, value, words):
    with pytest.raises(InputError) as error:
        SmtAllocatorParams(**{field: value})
    assert str(error.value).startswith(f"{field}: ") and words in str(error.value)
    assert "\n" not in str(error.value)
