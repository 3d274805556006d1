"""An independent checker of allocations: it recomputes everything from the problem's data
and shares no code with the allocators."""

from mrta_drake.allocation.problem import FEASIBLE, INFEASIBLE, Allocation, AllocationProblem
from mrta_drake.payloads import DROPOFF, PICKUP


def verify_allocation(
    problem: AllocationProblem,
    allocation: Allocation,
    keep_planned: bool = False,
    tolerance: float = 1e-6,
) -> tuple[str, ...]:
    """Every way ``allocation`` breaks the rules of ``problem``; empty when it is valid.

    Checks that every task is done once (pickup before drop-off, by one robot; items already
    on board dropped by their carrier), that no robot carries more than its capacity, that
    the times are the model's completion times (within ``tolerance`` s), that the late tasks
    are exactly those whose drop-off misses its deadline, and that the status agrees. With
    ``keep_planned`` each route must start with the robot's planned actions.
    """
    tasks = {task.id: task for task in problem.tasks}
    violations = []
    if len(allocation.routes) != len(problem.robots) or len(allocation.times) != len(
        problem.robots
    ):
        return (f"{len(allocation.routes)} routes and {len(allocation.times)} time lists "
                f"for {len(problem.robots)} robots",)
    picked, dropped, late = {}, {}, set()
    carried_by = {t: r for r, robot in enumerate(problem.robots) for t in robot.carrying}
    for r, (robot, route, times) in enumerate(
        zip(problem.robots, allocation.routes, allocation.times, strict=True)
    ):
        name = robot.name
        if len(times) != len(route):
            violations.append(f"{name}: {len(times)} times for {len(route)} actions")
            continue
        if keep_planned and tuple(route[: len(robot.planned)]) != tuple(robot.planned):
            violations.append(f"{name}: the planned actions were not kept")
        on_board = set(robot.carrying)
        clock, here = float(robot.ready_time), robot.location
        for action, claimed in zip(route, times, strict=True):
            task = tasks.get(action.task)
            if task is None:
                violations.append(f"{name}: task {action.task} is not in the problem")
                continue
            if action.kind == PICKUP:
                if action.task in carried_by or action.task in picked:
                    violations.append(f"{name}: task {task.id} picked up again")
                picked[task.id] = r
                on_board.add(task.id)
                there = task.pickup
            elif action.kind == DROPOFF:
                if action.task not in on_board:
                    violations.append(f"{name}: task {task.id} dropped off but not on board")
                if action.task in dropped:
                    violations.append(f"{name}: task {task.id} dropped off again")
                dropped[task.id] = r
                on_board.discard(task.id)
                there = task.dropoff
            else:
                violations.append(f"{name}: unknown action kind {action.kind!r}")
                continue
            if len(on_board) > robot.capacity:
                violations.append(f"{name}: carries {len(on_board)} items, capacity "
                                  f"{robot.capacity}")
            clock = max(clock, task.release) + problem.travel[here][there] + problem.service_time
            here = there
            if abs(clock - claimed) > tolerance:
                violations.append(f"{name}: {action.key} completes at {clock:g} s, not at "
                                  f"{claimed:g} s")
            if action.kind == DROPOFF and clock > task.deadline + tolerance:
                late.add(task.id)
        if on_board:
            violations.append(f"{name}: ends with tasks {sorted(on_board)} on board")
    for task_id in tasks:
        if task_id not in dropped:
            violations.append(f"task {task_id} is never dropped off")
    if set(allocation.late_tasks) != late:
        violations.append(f"late tasks are {sorted(late)}, the allocation says "
                          f"{sorted(allocation.late_tasks)}")
    if allocation.status == FEASIBLE and late:
        violations.append(f"status feasible but tasks {sorted(late)} are late")
    if allocation.status == INFEASIBLE and not late:
        violations.append("status infeasible but every task is on time")
    if not set(allocation.conflict) <= set(tasks):
        violations.append(f"conflict {sorted(allocation.conflict)} names unknown tasks")
    return tuple(violations)
