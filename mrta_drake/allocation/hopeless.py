"""Hopeless tasks: tasks no robot can drop off by their deadline, even doing nothing else.

Such a task is no decision for an exact search (it is late in every allocation), so
``solve_hopeful`` solves the problem without the open ones and then appends each of them,
earliest deadline first, to the end of the route where its drop-off is soonest (least
tardiness): the other tasks keep the times of the exact answer. docs/allocation.md.
"""

from collections.abc import Callable
from dataclasses import replace

from mrta_drake.allocation.problem import (
    INFEASIBLE,
    Action,
    Allocation,
    AllocationProblem,
    Task,
)
from mrta_drake.payloads import DROPOFF, PICKUP


def earliest_pickup(problem: AllocationProblem, task: Task) -> float:
    """A lower bound (s) on the completion of the open ``task``'s pickup in any allocation:
    the soonest any robot can get there from its start, and never before its release plus
    the service time."""
    service = problem.service_time
    reach = min(robot.ready_time + problem.travel[robot.location, task.pickup] + service
                for robot in problem.robots)
    return max(float(reach), task.release + service)


def earliest_drop_off(problem: AllocationProblem, task: Task) -> float:
    """A lower bound (s) on the completion of ``task``'s drop-off in any allocation (the
    travel times obey the triangle inequality, so doing other tasks first never helps)."""
    carrier = problem.carrier(task.id)
    service = problem.service_time
    if carrier is not None:
        robot = problem.robots[carrier]
        return float(robot.ready_time + problem.travel[robot.location, task.dropoff] + service)
    leg = float(problem.travel[task.pickup, task.dropoff] + service)
    return earliest_pickup(problem, task) + leg


def hopeless_tasks(problem: AllocationProblem) -> tuple[int, ...]:
    """The ids of the tasks whose earliest drop-off is after their deadline."""
    return tuple(task.id for task in problem.tasks
                 if earliest_drop_off(problem, task) > task.deadline)


def solve_hopeful(problem: AllocationProblem,
                  solve: Callable[[AllocationProblem], Allocation]) -> Allocation:
    """``solve`` on the problem without its open hopeless tasks, which are then appended.

    With any hopeless task the answer is ``INFEASIBLE`` (proven: that task alone is a
    conflict) and its note names the appended tasks; with any appended, it is not marked
    ``optimal`` (its tardiness is least for the others only). Hopeless tasks already on board stay
    in the problem ``solve`` gets (their items hold capacity along its routes)."""
    hopeless = hopeless_tasks(problem)
    if not hopeless:
        return solve(problem)
    open_hopeless = [problem.task(t) for t in hopeless if problem.carrier(t) is None]
    rest = solve(without_tasks(problem, {task.id for task in open_hopeless}))
    routes = [list(route) for route in rest.routes]
    for task in sorted(open_hopeless, key=lambda task: (task.deadline, task.id)):
        _append_soonest(problem, routes, task)
    allocation = Allocation.of(problem, routes)
    note = f"tasks {list(hopeless)} cannot be on time: appended last" if open_hopeless else ""
    return Allocation(
        routes=allocation.routes,
        times=allocation.times,
        status=INFEASIBLE,
        late_tasks=allocation.late_tasks,
        conflict=rest.conflict or (hopeless[0],),
        optimal=rest.optimal and not open_hopeless,
        solve_time=rest.solve_time,
        note="; ".join(part for part in (rest.note, note) if part),
        work=rest.work,
    )


def without_tasks(problem: AllocationProblem, task_ids: set[int]) -> AllocationProblem:
    """``problem`` less the tasks ``task_ids`` (none of them on board), also in the robots'
    ``planned`` actions."""
    robots = tuple(replace(robot, planned=tuple(
        action for action in robot.planned if action.task not in task_ids))
        for robot in problem.robots)
    return AllocationProblem(
        travel=problem.travel,
        robots=robots,
        tasks=tuple(task for task in problem.tasks if task.id not in task_ids),
        service_time=problem.service_time,
        source=problem.source,
    )


def _append_soonest(problem: AllocationProblem, routes: list[list[Action]], task: Task):
    """Appends ``task``'s pickup and drop-off to the route (lowest index on ties) where its
    drop-off completes soonest."""
    pair = [Action(task.id, PICKUP), Action(task.id, DROPOFF)]
    finish = [problem.completion_times(r, route + pair)[-1] for r, route in enumerate(routes)]
    best = min(range(len(routes)), key=lambda r: (finish[r], r))
    routes[best].extend(pair)
