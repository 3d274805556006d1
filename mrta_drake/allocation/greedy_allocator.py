"""GreedyAllocator: the cheapest-insertion baseline.

Tasks are taken earliest deadline first; each one's pickup and drop-off go into the robot
and the pair of route positions that add the fewest late tasks, then the least tardiness,
then the least delay to the end of that robot's route.
"""

import time as wallclock
from dataclasses import dataclass

from mrta_drake.allocation.problem import (
    Action,
    Allocation,
    AllocationProblem,
    solve_appending,
)
from mrta_drake.payloads import DROPOFF, PICKUP


@dataclass(frozen=True)
class GreedyAllocatorParams:
    """How the GreedyAllocator works. ``append_only`` keeps each robot's previous plan and
    inserts new tasks only after it; otherwise new tasks may go anywhere, and the allocator
    also tries planning every task afresh and keeps the better of the two."""

    append_only: bool = False


class GreedyAllocator:
    """Allocates tasks by cheapest feasible insertion; see ``GreedyAllocatorParams``."""

    def __init__(self, params: GreedyAllocatorParams = GreedyAllocatorParams()):
        self.params = params

    def allocate(self, problem: AllocationProblem) -> Allocation:
        start = wallclock.perf_counter()
        if self.params.append_only:
            allocation = solve_appending(problem, lambda rest: _Insertion(rest).run())
        else:
            fresh = _Insertion(problem).run()
            allocation = fresh
            if any(robot.planned for robot in problem.robots):
                kept = _Insertion(problem, [robot.planned for robot in problem.robots]).run()
                allocation = min(kept, fresh, key=lambda a: a.rank(problem))
        fields = dict(allocation.__dict__, solve_time=wallclock.perf_counter() - start)
        return Allocation(**fields)


class _Insertion:
    """Inserts every task that ``routes`` does not hold yet into them."""

    def __init__(self, problem: AllocationProblem, routes=None):
        self.problem = problem
        robots = problem.robots
        self.routes = [list(route) for route in routes] if routes else [[] for _ in robots]
        self.tasks = {task.id: task for task in problem.tasks}
        self.travel = problem.travel.tolist()  # (s) read as Python numbers: the same sums

    def run(self) -> Allocation:
        problem = self.problem
        placed = {action.task for route in self.routes for action in route}
        carriers = {task.id: problem.carrier(task.id) for task in problem.tasks}
        # Items on board go first: until their drop-offs are placed they hold capacity.
        order = sorted(problem.tasks, key=lambda t: (carriers[t.id] is None, t.deadline, t.id))
        for task in order:
            if task.id in placed:
                continue
            if carriers[task.id] is None:
                self._insert_pair(task.id)
            else:
                self._insert_drop(task.id, carriers[task.id])
        return Allocation.of(problem, self.routes)

    def _cost(self, robot: int, route: list[Action]):
        """(late tasks, tardiness, finish time) of ``route`` for robot index ``robot``, or
        None when it overloads the robot."""
        start = self.problem.robots[robot]
        load, time, here = len(start.carrying), start.ready_time, start.location
        late, tardiness = 0, 0.0
        travel, service, tasks = self.travel, self.problem.service_time, self.tasks
        for action in route:
            task = tasks[action.task]
            if action.kind == PICKUP:
                load += 1
                if load > start.capacity:
                    return None
                there = task.pickup
            else:
                load -= 1
                there = task.dropoff
            time = max(time, task.release) + travel[here][there] + service
            here = there
            if action.kind == DROPOFF and time > task.deadline:
                late += 1
                tardiness += time - task.deadline
        return late, tardiness, time

    def _insert_pair(self, task: int):
        pickup, drop = Action(task, PICKUP), Action(task, DROPOFF)
        best = None
        for robot, route in enumerate(self.routes):
            before = self._cost(robot, route)
            for i in range(len(route) + 1):
                for j in range(i, len(route) + 1):
                    trial = route[:i] + [pickup] + route[i:j] + [drop] + route[j:]
                    key = self._key(robot, trial, before)
                    if key is not None and (best is None or key < best[0]):
                        best = (key, robot, trial)
        self.routes[best[1]] = best[2]

    def _insert_drop(self, task: int, robot: int):
        drop, route = Action(task, DROPOFF), self.routes[robot]
        before = self._cost(robot, route)
        trials = [route[:i] + [drop] + route[i:] for i in range(len(route) + 1)]
        self.routes[robot] = min(trials, key=lambda trial: self._key(robot, trial, before))

    def _key(self, robot, trial, before):
        after = self._cost(robot, trial)
        if after is None:
            return None
        return (after[0] - before[0], after[1] - before[1], after[2] - before[2])
