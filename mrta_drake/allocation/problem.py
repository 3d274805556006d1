"""The allocation problem (SMrTa): a fleet, pickup-and-delivery tasks with deadlines, and the
allocator's answer.

Every time is in seconds of simulation time; every place is a location id ``0..L-1`` indexing
the travel-time matrix. A robot's route is the ordered actions it still has to do. Action ``k``
of a route completes at

    c_k = max(c_{k-1}, release of its task) + travel[l_{k-1}, l_k] + service_time

where ``c_0`` and ``l_0`` are the robot's ready time and location. A task is on time when its
drop-off completes by its deadline. Robots do not return home.
"""

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.payloads import DROPOFF, PICKUP

FEASIBLE = "feasible"  # every task is on time
INFEASIBLE = "infeasible"  # proven: no allocation has every task on time
UNKNOWN = "unknown"  # not proven either way (heuristic, or the time limit ran out)


def shortest_travel(travel: np.ndarray) -> np.ndarray:
    """Shortest travel times (s) allowing stops on the way (Floyd-Warshall closure), a new
    array. The closures of the last few matrices are kept: the allocator closes the same
    one at every update, and a building with hundreds of locations takes ~0.1 s for it."""
    matrix = np.array(travel, dtype=float)
    return _closure(matrix.shape, matrix.tobytes()).copy()


@functools.lru_cache(maxsize=4)
def _closure(shape: tuple[int, ...], data: bytes) -> np.ndarray:
    closure = np.frombuffer(data, dtype=float).reshape(shape).copy()
    for k in range(closure.shape[0]):
        np.minimum(closure, closure[:, k : k + 1] + closure[k : k + 1, :], out=closure)
    closure.flags.writeable = False
    return closure


@dataclass(frozen=True)
class Task:
    """Carry an item from ``pickup`` to ``dropoff`` (location ids), dropping it off by
    ``deadline`` (absolute, s). Nothing may be done for the task before ``release`` (s), the
    arrival of its batch."""

    id: int
    pickup: int
    dropoff: int
    deadline: float
    release: float = 0.0


@dataclass(frozen=True)
class Action:
    """The pickup or the drop-off (``kind``: ``PICKUP`` or ``DROPOFF``) of task ``task``."""

    task: int
    kind: str

    @property
    def key(self) -> str:
        """The stop key used on the ports, e.g. ``"t3/pickup"``."""
        return f"t{self.task}/{self.kind}"


@dataclass(frozen=True)
class RobotStart:
    """Where and when one robot starts the plan to be made.

    The robot is at ``location`` and free from ``ready_time`` (s) on, carrying the items of
    the tasks in ``carrying`` (their drop-offs are its to do). ``planned`` is the rest of its
    previous plan: a hint, or kept as it is by an append-only allocator.
    """

    name: str
    location: int
    ready_time: float = 0.0
    capacity: int = 2
    carrying: tuple[int, ...] = ()
    planned: tuple[Action, ...] = ()


@dataclass(frozen=True, eq=False)
class AllocationProblem:
    """One allocation to make: every task in ``tasks`` must be finished by some robot.

    A task listed in some robot's ``carrying`` needs only its drop-off, by that robot; every
    other task needs its pickup and then its drop-off by one robot. ``travel[a, b]`` is the
    travel time from location ``a`` to ``b`` (s, non-negative integers, may be asymmetric);
    it is stored as the shortest time over stops on the way, since a robot may drive through
    other locations, so the triangle inequality holds.
    """

    travel: np.ndarray
    robots: tuple[RobotStart, ...]
    tasks: tuple[Task, ...]
    service_time: float = 1.0
    source: str | None = None  # file the input came from, for error messages
    _task_index: dict = field(init=False, repr=False)

    def __post_init__(self):
        travel = np.array(self.travel)
        if travel.ndim != 2 or travel.shape[0] != travel.shape[1] or travel.shape[0] == 0:
            raise InputError(self.source, "travel", f"must be a square matrix, got {travel.shape}")
        if not np.all(np.isfinite(travel)) or np.any(travel < 0):
            raise InputError(self.source, "travel", "travel times must be finite and >= 0")
        if np.any(travel != np.round(travel)):
            raise InputError(self.source, "travel", "travel times must be whole seconds")
        travel = shortest_travel(travel).astype(np.int64)
        travel.flags.writeable = False
        object.__setattr__(self, "travel", travel)
        object.__setattr__(self, "robots", tuple(self.robots))
        object.__setattr__(self, "tasks", tuple(self.tasks))
        if not self.service_time > 0:
            raise InputError(self.source, "service_time", f"must be > 0, got {self.service_time}")
        index = {}
        for k, task in enumerate(self.tasks):
            where = f"tasks[{k}]"
            if task.id in index:
                raise InputError(self.source, f"{where}.id", f"duplicate task id {task.id}")
            index[task.id] = task
            self._check_location(f"{where}.pickup", task.pickup)
            self._check_location(f"{where}.dropoff", task.dropoff)
            if not task.deadline > task.release:
                raise InputError(
                    self.source,
                    f"{where}.deadline",
                    f"deadline {task.deadline:g} is not after the release {task.release:g}",
                )
        object.__setattr__(self, "_task_index", index)
        self._check_robots()

    @property
    def num_locations(self) -> int:
        return self.travel.shape[0]

    def task(self, task_id: int) -> Task:
        return self._task_index[task_id]

    def location(self, action: Action) -> int:
        task = self._task_index[action.task]
        return task.pickup if action.kind == PICKUP else task.dropoff

    def carrier(self, task_id: int) -> int | None:
        """Index of the robot carrying ``task_id``'s item, or None."""
        for r, robot in enumerate(self.robots):
            if task_id in robot.carrying:
                return r
        return None

    def completion_times(self, robot: int, route: Sequence[Action]) -> tuple[float, ...]:
        """Completion time (s) of each action of ``route`` done by robot index ``robot``."""
        start = self.robots[robot]
        time, here = float(start.ready_time), start.location
        times = []
        for action in route:
            there = self.location(action)
            task = self._task_index[action.task]
            time = max(time, task.release) + float(self.travel[here, there]) + self.service_time
            times.append(time)
            here = there
        return tuple(times)

    def _check_location(self, where: str, location: int):
        if not (isinstance(location, int | np.integer) and 0 <= location < self.num_locations):
            raise InputError(
                self.source,
                where,
                f"unknown location id {location!r} (locations are 0..{self.num_locations - 1})",
            )

    def _check_robots(self):
        owners = {}
        for r, robot in enumerate(self.robots):
            where = f"robots[{r}]"
            self._check_location(f"{where}.location", robot.location)
            if robot.capacity < 1:
                raise InputError(self.source, f"{where}.capacity", f"must be >= 1, got "
                                 f"{robot.capacity}")
            if len(robot.carrying) > robot.capacity:
                raise InputError(self.source, f"{where}.carrying", f"{len(robot.carrying)} items "
                                 f"exceed the capacity {robot.capacity}")
            for task_id in robot.carrying:
                if task_id not in self._task_index:
                    raise InputError(self.source, f"{where}.carrying", f"unknown task {task_id}")
                if task_id in owners:
                    raise InputError(self.source, f"{where}.carrying",
                                     f"task {task_id} is also carried by robot {owners[task_id]}")
                if self._task_index[task_id].release > robot.ready_time:
                    raise InputError(self.source, f"{where}.carrying", f"task {task_id} is "
                                     f"released at {self._task_index[task_id].release:g} s, "
                                     f"after the robot is ready ({robot.ready_time:g} s)")
                owners[task_id] = r
        planned = set()
        for r, robot in enumerate(self.robots):
            where = f"robots[{r}].planned"
            on_board = set(robot.carrying)
            for action in robot.planned:
                if action.task not in self._task_index or action.kind not in (PICKUP, DROPOFF):
                    raise InputError(self.source, where, f"unknown action {action.key}")
                if action.key in planned or (action.kind == PICKUP and action.task in owners):
                    raise InputError(self.source, where, f"action {action.key} is planned twice")
                planned.add(action.key)
                if action.kind == PICKUP:
                    on_board.add(action.task)
                elif action.task in on_board:
                    on_board.remove(action.task)
                else:
                    raise InputError(self.source, where,
                                     f"{action.key} comes before the item is on board")
            if on_board - set(robot.carrying):
                raise InputError(self.source, where, f"tasks {sorted(on_board)} are picked "
                                 "up but never dropped off")


@dataclass(frozen=True)
class Allocation:
    """An allocator's answer to an ``AllocationProblem``.

    ``routes[r]`` is robot ``r``'s actions in order (problem robot order) and ``times[r]``
    their predicted completion times (s). ``status`` is ``FEASIBLE`` (every task on time),
    ``INFEASIBLE`` (proven that no allocation has every task on time; these routes then serve
    as many tasks on time as the allocator could and the rest late) or ``UNKNOWN``.
    ``late_tasks`` are the tasks whose drop-off misses its deadline in these routes;
    ``conflict`` is a set of tasks that cannot all be on time together (an unsat core), when
    the allocator proved one. ``optimal`` says the objective was proven optimal (within the
    allocator's gap). ``solve_time`` is wall-clock seconds; ``work`` the solver's work in its
    own units (z3 resource units for the ``SmtAllocator``, 0 without a solver), the same on
    every host.
    """

    routes: tuple[tuple[Action, ...], ...]
    times: tuple[tuple[float, ...], ...]
    status: str
    late_tasks: tuple[int, ...] = ()
    conflict: tuple[int, ...] = ()
    optimal: bool = False
    solve_time: float = 0.0
    note: str = ""
    work: int = 0

    @classmethod
    def of(cls, problem: AllocationProblem, routes, status: str | None = None, **fields):
        """The allocation doing ``routes`` with times and late tasks computed; ``status``
        defaults to ``FEASIBLE`` when nothing is late and ``UNKNOWN`` otherwise."""
        routes = tuple(tuple(route) for route in routes)
        times = tuple(problem.completion_times(r, route) for r, route in enumerate(routes))
        late = tuple(sorted(
            action.task
            for route, route_times in zip(routes, times, strict=True)
            for action, time in zip(route, route_times, strict=True)
            if action.kind == DROPOFF and time > problem.task(action.task).deadline
        ))
        if status is None:
            status = UNKNOWN if late else FEASIBLE
        return cls(routes=routes, times=times, status=status, late_tasks=late, **fields)

    def drop_times(self) -> dict[int, float]:
        """Predicted drop-off completion time (s) per task id."""
        return {
            action.task: time
            for route, route_times in zip(self.routes, self.times, strict=True)
            for action, time in zip(route, route_times, strict=True)
            if action.kind == DROPOFF
        }

    def makespan(self) -> float:
        """Completion time (s) of the last action of any robot (0 when there is none)."""
        return max((times[-1] for times in self.times if times), default=0.0)

    def total_lateness(self, problem: AllocationProblem) -> float:
        """Sum over tasks of drop-off completion minus deadline (s; early tasks count
        negative)."""
        return sum(time - problem.task(t).deadline for t, time in self.drop_times().items())

    def total_tardiness(self, problem: AllocationProblem) -> float:
        """Sum over late tasks of how late their drop-off is (s)."""
        return sum(
            max(0.0, time - problem.task(t).deadline) for t, time in self.drop_times().items()
        )

    def rank(self, problem: AllocationProblem, write_off: float = math.inf,
             slack: float = 0.0) -> tuple[int, float, float, float, float]:
        """What the heuristics minimize, in order: late tasks, total tardiness (s), the room
        short of ``slack`` (s), total drop-off time (s) of the tasks not written off, and of
        those written off. A task whose drop-off is more than ``write_off`` (s) after its
        deadline is written off: its tardiness counts as ``write_off``, so it may go after
        every task that can still be on time (the default writes off nothing). A task not
        written off dropped off less than ``slack`` before its deadline is short of room by
        the difference (at most ``slack``: late tasks count in full), so that among plans
        equally late the tasks on time with little room get more (the default: none)."""
        late, tardiness, short, kept, written_off = len(self.late_tasks), 0.0, 0.0, 0.0, 0.0
        for t, time in self.drop_times().items():
            behind = time - problem.task(t).deadline
            if behind > write_off:
                tardiness += write_off
                written_off += time
            else:
                tardiness += max(0.0, behind)
                short += min(max(0.0, behind + slack), slack)
                kept += time
        return late, tardiness, short, kept, written_off


def keeping_planned(problem: AllocationProblem) -> AllocationProblem:
    """The problem left once every robot has done its ``planned`` actions: each robot starts
    where and when its planned actions end, and only the tasks they do not finish remain."""
    robots, finished = [], set()
    for r, robot in enumerate(problem.robots):
        times = problem.completion_times(r, robot.planned)
        on_board = list(robot.carrying)
        for action in robot.planned:
            if action.kind == PICKUP:
                on_board.append(action.task)
            else:
                on_board.remove(action.task)
                finished.add(action.task)
        robots.append(
            RobotStart(
                name=robot.name,
                location=problem.location(robot.planned[-1]) if robot.planned else robot.location,
                ready_time=times[-1] if times else robot.ready_time,
                capacity=robot.capacity,
                carrying=tuple(on_board),
            )
        )
    return AllocationProblem(
        travel=problem.travel,
        robots=tuple(robots),
        tasks=tuple(task for task in problem.tasks if task.id not in finished),
        service_time=problem.service_time,
        source=problem.source,
    )


def solve_appending(
    problem: AllocationProblem, solve: Callable[[AllocationProblem], Allocation]
) -> Allocation:
    """Keeps every robot's planned actions as they are and lets ``solve`` place the remaining
    tasks after them (the append-only behaviour of the original stack)."""
    rest = solve(keeping_planned(problem))
    routes = [robot.planned + route for robot, route in zip(problem.robots, rest.routes,
                                                             strict=True)]
    allocation = Allocation.of(problem, routes)
    kept_late = tuple(t for t in allocation.late_tasks if t not in rest.late_tasks)
    if kept_late and rest.status != UNKNOWN:
        status = INFEASIBLE  # the kept actions fix those tasks' times
    else:
        status = rest.status
    return Allocation(
        routes=allocation.routes,
        times=allocation.times,
        status=status,
        late_tasks=allocation.late_tasks,
        conflict=tuple(sorted(set(rest.conflict) | set(kept_late))),
        optimal=rest.optimal,
        solve_time=rest.solve_time,
        note=rest.note,
        work=rest.work,
    )


@dataclass(frozen=True)
class RobotStatus:
    """What one robot has done when a new allocation is made.

    It last completed an action (or started) at ``location`` at ``time`` (s, measured), has
    the items of ``carrying`` on board, and is driving to do ``current`` (None when idle).
    """

    name: str
    location: int
    time: float = 0.0
    capacity: int = 2
    carrying: tuple[int, ...] = ()
    current: Action | None = None


def committed_start(
    status: RobotStatus,
    now: float,
    tasks: dict[int, Task],
    travel: np.ndarray,
    service_time: float,
    planned: tuple[Action, ...] = (),
) -> RobotStart:
    """Where and when a robot is free for a plan made at ``now`` (s): after the action it is
    driving to, which is committed, and never before ``now``. ``tasks`` maps task ids to
    tasks; ``planned`` is the rest of its previous plan after the current action."""
    location, ready, carrying = status.location, status.time, list(status.carrying)
    if status.current is not None:
        task = tasks[status.current.task]
        there = task.pickup if status.current.kind == PICKUP else task.dropoff
        ready = max(ready, task.release) + float(travel[location, there]) + service_time
        location = there
        if status.current.kind == PICKUP:
            carrying.append(task.id)
        else:
            carrying.remove(task.id)
    return RobotStart(
        name=status.name,
        location=location,
        ready_time=max(ready, now),
        capacity=status.capacity,
        carrying=tuple(carrying),
        planned=planned,
    )


def stream_tasks(stream: Sequence) -> tuple[tuple[Task, ...], ...]:
    """The tasks of each batch of ``stream``, with ids numbered from 0 in stream order and
    released at their batch's arrival.

    A batch is anything with ``arrival`` (s) and ``tasks``, each task with ``pickup`` and
    ``dropoff`` (location ids) and ``deadline`` (absolute, s), e.g.
    ``mrta_drake.scenario.schema.TaskBatch``."""
    batches, next_id = [], 0
    for batch in stream:
        tasks = []
        for request in batch.tasks:
            tasks.append(Task(next_id, request.pickup, request.dropoff, float(request.deadline),
                              float(batch.arrival)))
            next_id += 1
        batches.append(tuple(tasks))
    return tuple(batches)


def check_stream(stream: Sequence, num_locations: int, source: str | None = None):
    """Raises ``InputError`` unless arrivals are >= 0 and in order, locations are ids below
    ``num_locations`` and every deadline is after its batch's arrival."""
    previous = 0.0
    for b, batch in enumerate(stream):
        where = f"tasks_stream[{b}]"
        if not (np.isfinite(batch.arrival) and batch.arrival >= previous):
            raise InputError(source, f"{where}.arrival", f"arrival {batch.arrival} is negative "
                             f"or before the previous batch's ({previous:g})")
        previous = batch.arrival
        for k, request in enumerate(batch.tasks):
            for name in ("pickup", "dropoff"):
                location = getattr(request, name)
                if not (isinstance(location, int | np.integer) and 0 <= location < num_locations):
                    raise InputError(source, f"{where}.tasks[{k}].{name}",
                                     f"unknown location id {location!r} "
                                     f"(locations are 0..{num_locations - 1})")
            if not request.deadline > batch.arrival:
                raise InputError(source, f"{where}.tasks[{k}].deadline",
                                 f"deadline {request.deadline:g} is not after the batch "
                                 f"arrival {batch.arrival:g}")
