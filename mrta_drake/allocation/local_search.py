"""Local search on routes: improves an allocation by moving tasks between and within robots.

An allocation is ranked by ``Allocation.rank``: fewest late tasks, then least total
tardiness (s), then (with ``slack``) the least room short of ``slack`` before the deadlines,
then least total drop-off time (s); with ``write_off`` a task planned more than that late
counts only that much tardiness and its drop-off time ranks after the others' (it goes after
the tasks that can still be on time). Three moves, tried in a fixed order until
none improves the rank (first improvement, no randomness, so the same allocation always
improves to the same answer):

- relocate: take a task's pickup and drop-off out of its route and insert them where they
  rank best, on any robot (the same robot included);
- swap: exchange two tasks of different robots, each inserted where it ranks best in the
  other's route;
- 2-opt: reverse a stretch of one route, when its pickups still come before their drop-offs.

Items already on board (a robot's ``carrying``) stay with their carrier; their drop-offs move
only within the route, by 2-opt. Capacity holds in every route tried.
"""

import dataclasses
import math
from dataclasses import dataclass

from mrta_drake.allocation.problem import FEASIBLE, Action, Allocation, AllocationProblem
from mrta_drake.errors import InputError
from mrta_drake.payloads import DROPOFF, PICKUP

MAX_ROUNDS = 50  # rounds of all three moves, at most (each round improves the rank)
MAX_EVALUATIONS = 400_000  # routes evaluated, at most: about 1 s of CPU on the reference machine
TOLERANCE = 1e-9  # s: a rank must improve by more than this


@dataclass(frozen=True)
class LocalSearchParams:
    """``max_rounds``: at most this many rounds of relocate, swap and 2-opt;
    ``max_evaluations``: at most this many routes evaluated (a count, not a time, so the
    answer is the same on any host), checked before each task a move tries; ``write_off``
    and ``slack`` (s): the rank's (``Allocation.rank``), infinite and 0 by default."""

    max_rounds: int = MAX_ROUNDS
    max_evaluations: int = MAX_EVALUATIONS
    write_off: float = math.inf
    slack: float = 0.0

    def __post_init__(self):
        for name in ("max_rounds", "max_evaluations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InputError(None, name, f"must be a whole number >= 0, got {value!r}")
        for name in ("write_off", "slack"):
            value = getattr(self, name)
            if not value >= 0:
                raise InputError(None, name, f"must be >= 0 s, got {value!r}")


def improve(problem: AllocationProblem, allocation: Allocation,
            params: LocalSearchParams = LocalSearchParams()) -> Allocation:
    """``allocation`` improved by relocate, swap and 2-opt moves until none helps; never
    ranks worse than ``allocation``. The status is recomputed (``FEASIBLE`` when every task
    is on time, else ``UNKNOWN``)."""
    search = _Routes(problem, allocation.routes, params.max_evaluations, params.write_off,
                     params.slack)
    for _ in range(params.max_rounds):
        if not (search.relocate() or search.swap() or search.two_opt()):
            break
    improved = Allocation.of(problem, search.routes)
    rank = (params.write_off, params.slack)
    if improved.rank(problem, *rank) < allocation.rank(problem, *rank):
        return improved
    return allocation


def improve_keeping_verdict(problem: AllocationProblem, allocation: Allocation,
                            params: LocalSearchParams = LocalSearchParams()) -> Allocation:
    """``allocation`` with the routes ``improve`` finds, keeping the allocator's status,
    conflict, note, solve time and work (local search never adds a late task, so what the
    allocator proved still holds), and its optimality unless tardiness was traded for the
    drop-offs of the tasks not written off; ``FEASIBLE`` once nothing is late."""
    improved = improve(problem, allocation, params)
    if improved is allocation:
        return allocation
    status = FEASIBLE if not improved.late_tasks else allocation.status
    optimal = allocation.optimal and (improved.total_tardiness(problem)
                                      <= allocation.total_tardiness(problem))
    return dataclasses.replace(allocation, routes=improved.routes, times=improved.times,
                               late_tasks=improved.late_tasks, status=status, optimal=optimal)


class _Routes:
    """The routes being improved, with each one's cost (late, tardiness, room short of the
    slack, drop-off times)."""

    def __init__(self, problem: AllocationProblem, routes, max_evaluations: int,
                 write_off: float, slack: float):
        self.problem = problem
        self.evaluations_left = max_evaluations
        self.write_off = write_off
        self.slack = slack
        self.travel = problem.travel.tolist()
        self.service = problem.service_time
        self.task = {task.id: task for task in problem.tasks}
        self.routes = [list(route) for route in routes]
        self.costs = [self.cost(r, route) for r, route in enumerate(self.routes)]

    def cost(self, robot: int, route: list[Action]):
        """(late tasks, tardiness, room short of the slack, sum of drop-off times of the tasks
        not written off, and of those written off; see ``Allocation.rank``) of ``route`` for
        robot index ``robot``, or None when it overloads the robot or drops an item not on
        board."""
        self.evaluations_left -= 1
        start = self.problem.robots[robot]
        on_board = set(start.carrying)
        time, here = float(start.ready_time), start.location
        late, tardiness, short, drops, written_off = 0, 0.0, 0.0, 0.0, 0.0
        for action in route:
            task = self.task[action.task]
            if action.kind == PICKUP:
                on_board.add(task.id)
                if len(on_board) > start.capacity:
                    return None
                there = task.pickup
            else:
                if task.id not in on_board:
                    return None
                on_board.remove(task.id)
                there = task.dropoff
            time = max(time, task.release) + self.travel[here][there] + self.service
            here = there
            if action.kind == DROPOFF:
                behind = time - task.deadline
                if behind > self.write_off:
                    late += 1
                    tardiness += self.write_off
                    written_off += time
                    continue
                drops += time
                short += min(max(0.0, behind + self.slack), self.slack)
                if behind > 0:
                    late += 1
                    tardiness += behind
        return late, tardiness, short, drops, written_off

    def _better(self, new_costs, old_costs) -> bool:
        new = _sum(new_costs)
        old = _sum(old_costs)
        if new[0] != old[0]:
            return new[0] < old[0]
        for a, b in zip(new[1:], old[1:], strict=True):
            if abs(a - b) > TOLERANCE:
                return a < b
        return False

    def _best_insertion(self, robot: int, route: list[Action], task: int):
        """The cheapest route and its cost with ``task``'s pickup and drop-off inserted into
        ``route`` (None when no insertion fits the robot)."""
        pickup, drop = Action(task, PICKUP), Action(task, DROPOFF)
        best = None
        for i in range(len(route) + 1):
            for j in range(i, len(route) + 1):
                trial = route[:i] + [pickup] + route[i:j] + [drop] + route[j:]
                cost = self.cost(robot, trial)
                if cost is not None and (best is None or self._better([cost], [best[1]])):
                    best = (trial, cost)
        return best

    def _movable(self, robot: int):
        """The tasks whose pickup is on ``robot``'s route, in route order."""
        return [a.task for a in self.routes[robot] if a.kind == PICKUP]

    def relocate(self) -> bool:
        """Moves the first task whose best re-insertion improves the rank."""
        for source in range(len(self.routes)):
            for task in self._movable(source):
                if self.evaluations_left <= 0:
                    return False
                rest = [a for a in self.routes[source] if a.task != task]
                rest_cost = self.cost(source, rest)
                for target in range(len(self.routes)):
                    base = rest if target == source else self.routes[target]
                    found = self._best_insertion(target, base, task)
                    if found is None:
                        continue
                    if target == source:
                        changed = {source: found}
                    else:
                        changed = {source: (rest, rest_cost), target: found}
                    if self._apply_if_better(changed):
                        return True
        return False

    def swap(self) -> bool:
        """Exchanges the first pair of tasks on two robots whose exchange improves the
        rank."""
        for a in range(len(self.routes)):
            for b in range(a + 1, len(self.routes)):
                for i in self._movable(a):
                    for j in self._movable(b):
                        if self.evaluations_left <= 0:
                            return False
                        rest_a = [x for x in self.routes[a] if x.task != i]
                        rest_b = [x for x in self.routes[b] if x.task != j]
                        into_a = self._best_insertion(a, rest_a, j)
                        into_b = self._best_insertion(b, rest_b, i)
                        if into_a is None or into_b is None:
                            continue
                        if self._apply_if_better({a: into_a, b: into_b}):
                            return True
        return False

    def two_opt(self) -> bool:
        """Reverses the first stretch of a route whose reversal improves the rank."""
        for robot, route in enumerate(self.routes):
            if self.evaluations_left <= 0:
                return False
            for i in range(len(route) - 1):
                for j in range(i + 2, len(route) + 1):
                    trial = route[:i] + route[i:j][::-1] + route[j:]
                    cost = self.cost(robot, trial)
                    if cost is not None and self._apply_if_better({robot: (trial, cost)}):
                        return True
        return False

    def _apply_if_better(self, changed: dict) -> bool:
        """Takes the routes of ``changed`` (robot: (route, cost)) when together they rank
        better than the routes they replace."""
        new = [cost for _, cost in changed.values()]
        old = [self.costs[robot] for robot in changed]
        if not self._better(new, old):
            return False
        for robot, (route, cost) in changed.items():
            self.routes[robot], self.costs[robot] = route, cost
        return True


def _sum(costs):
    """The costs added up field by field, in order (as ``sum`` adds)."""
    late, tardiness, short, drops, written_off = 0, 0, 0, 0, 0
    for cost in costs:
        late += cost[0]
        tardiness += cost[1]
        short += cost[2]
        drops += cost[3]
        written_off += cost[4]
    return late, tardiness, short, drops, written_off
