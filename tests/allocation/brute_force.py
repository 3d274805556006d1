"""An exhaustive reference solver for tiny problems (a few robots and tasks), for tests: it
tries every assignment of tasks to robots and every order of each robot's actions."""

import itertools
import math
from dataclasses import dataclass

import pytest

from mrta_drake.allocation.hopeless import hopeless_tasks, without_tasks
from mrta_drake.allocation.problem import Allocation, AllocationProblem


@dataclass(frozen=True)
class Optimum:
    """The best any allocation of a problem can do.

    ``most_on_time`` tasks can be on time, with ``least_tardiness`` (s) total tardiness
    among allocations with that many on time; ``feasible`` says every task can be. Among the
    allocations with every task on time, ``least_makespan`` and ``least_total_drop_time``
    (s) are the best (``inf`` when there is none).
    """

    feasible: bool
    most_on_time: int
    least_tardiness: float
    least_makespan: float
    least_total_drop_time: float


@dataclass
class _RouteBest:
    on_time: int = -1
    tardiness: float = math.inf
    makespan: float = math.inf  # these two among routes with every task on time
    drop_time: float = math.inf


def brute_force(problem: AllocationProblem) -> Optimum:
    """The exact ``Optimum`` of ``problem``; the work grows like R^T (2T)!, keep it tiny."""
    open_tasks = [task.id for task in problem.tasks if problem.carrier(task.id) is None]
    best_routes = {}
    for r in range(len(problem.robots)):
        for size in range(len(open_tasks) + 1):
            for subset in itertools.combinations(open_tasks, size):
                best_routes[r, frozenset(subset)] = _best_route(problem, r, subset)
    most, least, makespan, drop_time = -1, math.inf, math.inf, math.inf
    for choice in itertools.product(range(len(problem.robots)), repeat=len(open_tasks)):
        routes = [
            best_routes[r, frozenset(t for t, c in zip(open_tasks, choice, strict=True) if c == r)]
            for r in range(len(problem.robots))
        ]
        on_time = sum(route.on_time for route in routes)
        tardiness = sum(route.tardiness for route in routes)
        if (on_time, -tardiness) > (most, -least):
            most, least = on_time, tardiness
        if on_time == len(problem.tasks):
            makespan = min(makespan, max(route.makespan for route in routes))
            drop_time = min(drop_time, sum(route.drop_time for route in routes))
    return Optimum(
        feasible=most == len(problem.tasks),
        most_on_time=most,
        least_tardiness=least,
        least_makespan=makespan,
        least_total_drop_time=drop_time,
    )


def _best_route(problem: AllocationProblem, robot: int, subset) -> _RouteBest:
    start = problem.robots[robot]
    tasks = [problem.task(t) for t in (*start.carrying, *subset)]
    best = _RouteBest()

    def extend(time, here, waiting, on_board, on_time, tardiness, drop_time):
        if not waiting and not on_board:
            if (on_time, -tardiness) > (best.on_time, -best.tardiness):
                best.on_time, best.tardiness = on_time, tardiness
            if on_time == len(tasks):
                best.makespan = min(best.makespan, time if tasks else 0.0)
                best.drop_time = min(best.drop_time, drop_time)
            return
        for task in waiting:
            if len(on_board) < start.capacity:
                done = max(time, task.release) + problem.travel[here, task.pickup]
                extend(done + problem.service_time, task.pickup, waiting - {task},
                       on_board | {task}, on_time, tardiness, drop_time)
        for task in on_board:
            done = max(time, task.release) + problem.travel[here, task.dropoff]
            done += problem.service_time
            late = max(0.0, done - task.deadline)
            extend(done, task.dropoff, waiting, on_board - {task}, on_time + (late == 0),
                   tardiness + late, drop_time + done)

    carried = frozenset(problem.task(t) for t in start.carrying)
    waiting = frozenset(problem.task(t) for t in subset)
    extend(float(start.ready_time), start.location, waiting, carried, 0, 0.0, 0.0)
    return best


def assert_optimum(problem: AllocationProblem, allocation: Allocation, best: Optimum,
                   defer_hopeless: bool) -> None:
    """``allocation`` has the most tasks on time of ``best``; and the least tardiness, over
    the whole problem (then marked ``optimal``), or with ``defer_hopeless`` and any open
    hopeless task appended, over the tasks searched (then not marked ``optimal``)."""
    assert len(problem.tasks) - len(allocation.late_tasks) == best.most_on_time
    if defer_hopeless and any(problem.carrier(t) is None for t in hopeless_tasks(problem)):
        assert not allocation.optimal
        tardiness, least = hopeful_tardiness(problem, allocation)
        assert tardiness == pytest.approx(least)
    else:
        assert allocation.optimal
        assert allocation.total_tardiness(problem) == pytest.approx(best.least_tardiness)


def hopeful_tardiness(problem: AllocationProblem, allocation: Allocation) -> tuple[float, float]:
    """The total tardiness (s) of ``allocation`` over the tasks the SMT allocator searches
    (all but the open hopeless ones, which it appends), and the least exhaustive search
    finds for them."""
    appended = {t for t in hopeless_tasks(problem) if problem.carrier(t) is None}
    tardiness = sum(max(0.0, time - problem.task(t).deadline)
                    for t, time in allocation.drop_times().items() if t not in appended)
    return tardiness, brute_force(without_tasks(problem, appended)).least_tardiness
