"""The SMT encoding's cuts (symmetry breaking between robots at the same start, bounds on how
many tasks a robot can finish on time) never cut an optimal answer: on small tight problems
where they apply, the allocator still finds exhaustive search's optimum."""

import itertools

import pytest
import z3

from mrta_drake.allocation import SmtAllocator, SmtAllocatorParams, verify_allocation
from mrta_drake.allocation.smt_allocator import _Encoding
from tests.allocation.brute_force import assert_optimum, brute_force
from tests.allocation.tight_instances import tight_problem

CASES = [(seed, same_start, capacity) for seed in range(12) for same_start in (True, False)
         for capacity in (1, 2)]
LATEST = 100  # s: the latest deadline


def robot_bounds(problem) -> list:
    encoding = _Encoding(problem, z3.SimpleSolver(ctx=z3.Context()), lambda: None)
    return encoding.robot_bounds


@pytest.mark.parametrize("seed, same_start, capacity", CASES)
def test_cuts_keep_the_optimum(seed, same_start, capacity):
    problem = tight_problem(seed, 4, 3, same_start, LATEST, capacity)
    best = brute_force(problem)
    for greedy_start, defer in itertools.product((True, False), (True, False)):
        params = SmtAllocatorParams(greedy_start=greedy_start, objective_gap=0.5,
                                    defer_hopeless=defer)
        allocation = SmtAllocator(params).allocate(problem)
        assert verify_allocation(problem, allocation) == ()
        assert_optimum(problem, allocation, best, defer)


def test_the_cases_exercise_the_cuts():
    problems = [tight_problem(seed, 4, 3, same_start, LATEST, capacity)
                for seed, same_start, capacity in CASES]
    assert sum(bool(robot_bounds(problem)) for problem in problems) >= len(problems) // 3
    assert sum(not brute_force(problem).feasible for problem in problems) >= len(problems) // 3
