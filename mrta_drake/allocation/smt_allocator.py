"""SmtAllocator: allocation by SMT solving (z3), complete, with proofs of infeasibility.

The encoding is disjunctive, as for job-shop scheduling, instead of a fixed number of action
slots per robot: Booleans say which robot does each task and, for two actions that end up
on the same robot, which comes first; times are linked by difference constraints. A robot
may do any number of actions, so an ``INFEASIBLE`` answer is a proof. docs/allocation.md
gives the formulas.
"""

import ctypes
import itertools
import math
import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass

import z3

from mrta_drake.allocation.greedy_allocator import GreedyAllocator
from mrta_drake.allocation.hopeless import earliest_pickup, solve_hopeful
from mrta_drake.allocation.local_search import improve
from mrta_drake.allocation.problem import (
    FEASIBLE,
    INFEASIBLE,
    UNKNOWN,
    Action,
    Allocation,
    AllocationProblem,
    solve_appending,
)
from mrta_drake.errors import InputError
from mrta_drake.payloads import DROPOFF, PICKUP

OBJECTIVES = ("none", "makespan", "lateness")
TIGHTEN_STEP = 0.1  # of the range left between the best value and the lower bound
CORE_SHARE = 0.25  # of the budget (and time limit), at most, spent making a conflict minimal
# z3 resource units (``rlimit``) for one allocate call: about 10 s of solving on the reference
# machine (2 shared cores; benchmarks/allocation_budget.py, docs/allocation.md).
DEFAULT_BUDGET = 48_000_000
MAX_BUDGET = 2**32 - 1  # z3 takes a check's resource limit as an unsigned 32-bit integer


@dataclass(frozen=True)
class SmtAllocatorParams:
    """How the SmtAllocator works.

    ``objective``: ``"none"`` (any allocation with every task on time), ``"makespan"`` (the
    last action done earliest) or ``"lateness"`` (least total lateness: the sum over tasks
    of drop-off time minus deadline). Optimized by bisection on a bound until within
    ``objective_gap`` (s) of the optimum. When not every task can be on time the allocator
    instead serves the most tasks on time and then the least total tardiness (the late
    tasks as early as possible), whatever the objective. With ``defer_hopeless`` tasks that
    cannot be on time even alone (``hopeless.hopeless_tasks``) are left out of that search
    and appended afterwards (least tardiness each, ``hopeless.solve_hopeful``): the most
    tasks on time stays exact, the least tardiness is that of the others (the answer is
    then not marked ``optimal``); cheap under overload. Without it the search takes every
    task, exact in both.

    ``budget`` bounds the solver work of one ``allocate`` call in z3 resource units
    (``rlimit``, a count of z3's steps, the same on every host), so that answers depend only
    on the problem; the default is about 10 s of solving on the reference machine. When it
    runs out the best allocation found so far is returned (at worst the greedy one) with a
    note saying so. ``time_limit`` (s, wall clock; None: none) adds a wall-clock bound;
    answers it cuts short depend on the host's speed and load, so runs are not reproducible.
    ``greedy_start`` runs the greedy allocator first (improved by local search when it
    leaves tasks late) and starts from its answer: when that has every task on time it
    already proves feasibility. ``append_only`` keeps each robot's
    previous plan and places new tasks after it. ``random_seed`` is z3's.
    """

    objective: str = "none"
    budget: int = DEFAULT_BUDGET
    time_limit: float | None = None
    objective_gap: float = 1.0
    greedy_start: bool = True
    append_only: bool = False
    random_seed: int = 0
    defer_hopeless: bool = True

    def __post_init__(self):
        if self.objective not in OBJECTIVES:
            raise InputError(None, "objective", f"unknown objective {self.objective!r} "
                             f"(one of {', '.join(OBJECTIVES)})")
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or not (
                0 < self.budget <= MAX_BUDGET):
            raise InputError(None, "budget", f"must be a whole number of z3 resource units "
                             f"from 1 to {MAX_BUDGET}, got {self.budget!r}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise InputError(None, "time_limit", f"must be > 0 s, or null for none, got "
                             f"{self.time_limit}")
        if not self.objective_gap > 0:
            raise InputError(None, "objective_gap", f"must be > 0 s, got {self.objective_gap}")


class SmtAllocator:
    """Allocates tasks by SMT solving; see ``SmtAllocatorParams`` for the options."""

    def __init__(self, params: SmtAllocatorParams = SmtAllocatorParams()):
        self.params = params

    def allocate(self, problem: AllocationProblem) -> Allocation:
        start = wallclock.perf_counter()
        if self.params.append_only:
            allocation = solve_appending(problem, self._solve_hopeful)
        else:
            allocation = self._solve_hopeful(problem)
        return _replace(allocation, solve_time=wallclock.perf_counter() - start)

    def _solve_hopeful(self, problem: AllocationProblem) -> Allocation:
        """With ``defer_hopeless``: the exact answer for the tasks that can still be on
        time, the hopeless ones appended (``hopeless.solve_hopeful``); else the exact
        answer for all."""
        if not self.params.defer_hopeless:
            return _Solve(problem, self.params).run()
        return solve_hopeful(problem, lambda rest: _Solve(rest, self.params).run())


@dataclass(frozen=True)
class _Limit:
    """Where solving stops: once the allocation's z3 context has counted ``units`` resource
    units, or (opted in) at ``stop_time`` (s, ``time.perf_counter``)."""

    units: int
    stop_time: float | None = None


class _OutOfBudget(Exception):
    """The budget or the time limit ran out while the encoding was being built."""


class _Terms:
    """Makes z3 terms through z3's C API (``z3.Z3_mk_*``), without the argument checks and
    conversions of z3's Python functions: a term costs a fraction of the Python work.

    Each method makes exactly the C calls of the z3 function it names, and returns a new
    Python reference (``z3.AstRef``) as that function does. z3 numbers its terms in the
    order they are made and reuses the numbers of terms it frees (when their last reference
    goes), and its answers depend on those numbers: code that makes the same calls and holds
    the returned references as long as code calling z3's functions gets the same terms,
    numbered alike, and the same answers.
    """

    def __init__(self, ctx: z3.Context):
        self.ctx = ctx
        self.ref = ctx.ref()
        self._bool = z3.Z3_mk_bool_sort(self.ref)
        self._real = z3.Z3_mk_real_sort(self.ref)

    def bool(self, name: str) -> z3.BoolRef:
        """``z3.Bool(name)``."""
        symbol = z3.Z3_mk_string_symbol(self.ref, name)
        return z3.BoolRef(z3.Z3_mk_const(self.ref, symbol, self._bool), self.ctx)

    def real(self, name: str) -> z3.ArithRef:
        """``z3.Real(name)``."""
        symbol = z3.Z3_mk_string_symbol(self.ref, name)
        return z3.ArithRef(z3.Z3_mk_const(self.ref, symbol, self._real), self.ctx)

    def value(self, value: bool) -> z3.BoolRef:
        """``z3.BoolVal(value)``."""
        if value:
            return z3.BoolRef(z3.Z3_mk_true(self.ref), self.ctx)
        return z3.BoolRef(z3.Z3_mk_false(self.ref), self.ctx)

    def number(self, value: float) -> z3.RatNumRef:
        """``z3.RealVal(value)`` (made from ``str(value)``)."""
        return z3.RatNumRef(z3.Z3_mk_numeral(self.ref, str(value), self._real), self.ctx)

    def negation(self, a: z3.BoolRef) -> z3.BoolRef:
        """``z3.Not(a)``."""
        return z3.BoolRef(z3.Z3_mk_not(self.ref, a.ast), self.ctx)

    def any(self, *args: z3.BoolRef) -> z3.BoolRef:
        """``z3.Or(*args)``."""
        return z3.BoolRef(z3.Z3_mk_or(self.ref, len(args), _array(args)), self.ctx)

    def all(self, *args: z3.BoolRef) -> z3.BoolRef:
        """``z3.And(*args)``."""
        return z3.BoolRef(z3.Z3_mk_and(self.ref, len(args), _array(args)), self.ctx)

    def implies(self, a: z3.BoolRef, b: z3.BoolRef) -> z3.BoolRef:
        """``z3.Implies(a, b)``."""
        return z3.BoolRef(z3.Z3_mk_implies(self.ref, a.ast, b.ast), self.ctx)

    def equal(self, a: z3.BoolRef, b: z3.BoolRef) -> z3.BoolRef:
        """``a == b``."""
        return z3.BoolRef(z3.Z3_mk_eq(self.ref, a.ast, b.ast), self.ctx)

    def at_least(self, a: z3.ArithRef, b) -> z3.BoolRef:
        """``a >= b``, ``b`` a real term or a number."""
        if not isinstance(b, z3.AstRef):
            b = self.number(b)
        return z3.BoolRef(z3.Z3_mk_ge(self.ref, a.ast, b.ast), self.ctx)

    def at_most(self, a: z3.ArithRef, b) -> z3.BoolRef:
        """``a <= b``, ``b`` a real term or a number."""
        if not isinstance(b, z3.AstRef):
            b = self.number(b)
        return z3.BoolRef(z3.Z3_mk_le(self.ref, a.ast, b.ast), self.ctx)

    def plus(self, a: z3.ArithRef, b: float) -> z3.ArithRef:
        """``a + b``, ``b`` a number."""
        b = self.number(b)
        return z3.ArithRef(z3.Z3_mk_add(self.ref, 2, _array((a, b))), self.ctx)

    def pb_equal(self, pairs, k: int) -> z3.BoolRef:
        """``z3.PbEq(pairs, k)``: ``pairs`` of (literal, whole coefficient)."""
        return z3.BoolRef(z3.Z3_mk_pbeq(self.ref, len(pairs), *_pb(pairs), k), self.ctx)

    def pb_at_most(self, pairs, k: int) -> z3.BoolRef:
        """``z3.PbLe(pairs, k)``."""
        return z3.BoolRef(z3.Z3_mk_pble(self.ref, len(pairs), *_pb(pairs), k), self.ctx)

    def prefer(self, solver: z3.Solver, literal: z3.BoolRef, value: bool):
        """``solver.set_initial_value(literal, value)`` (no term made: true and false are
        z3's own, never freed)."""
        value = z3.Z3_mk_true(self.ref) if value else z3.Z3_mk_false(self.ref)
        z3.Z3_solver_set_initial_value(self.ref, solver.solver, literal.ast, value)

    def count_at_most(self, args, k: int) -> z3.BoolRef:
        """``z3.AtMost(*args, k)``."""
        return z3.BoolRef(z3.Z3_mk_atmost(self.ref, len(args), _array(args), k), self.ctx)


def _array(terms) -> ctypes.Array:
    """The C array of ``terms``' ASTs."""
    return (z3.Ast * len(terms))(*[term.ast for term in terms])


def _pb(pairs):
    """The C arrays of literals and coefficients of (literal, coefficient) ``pairs``."""
    return (_array([literal for literal, _ in pairs]),
            (ctypes.c_int * len(pairs))(*[coefficient for _, coefficient in pairs]))


class _Encoding:
    """The z3 variables and constraints of one problem.

    Per task ``i``: ``assigned[i, r]`` (robot ``r`` does it), ``on_time[i]`` (the deadline
    literal, asserted by assumption) and the completion times ``time[action]``. Per pair of
    actions of different tasks that may share a robot: ``first[a, b]`` (``a`` before ``b``
    when they do).

    Every term lives in ``solver``'s context, made by ``_Terms`` as z3's Python functions
    would make it (the same terms, numbered alike, so the same answers). ``check_limit`` is
    called now and then while the constraints are added; it raises ``_OutOfBudget`` to
    stop. It is not kept, so the encoding holds no reference back to its caller and is freed
    with it.
    """

    def __init__(self, problem: AllocationProblem, solver: z3.Solver,
                 check_limit: Callable[[], None]):
        self.problem = problem
        self.solver = solver
        self.terms = terms = _Terms(solver.ctx)
        robots, travel, service = problem.robots, problem.travel, problem.service_time
        self.carrier = {task.id: problem.carrier(task.id) for task in problem.tasks}
        self.actions = []
        for task in problem.tasks:
            if self.carrier[task.id] is None:
                self.actions.append(Action(task.id, PICKUP))
            self.actions.append(Action(task.id, DROPOFF))
        self.time = {action: terms.real(f"t_{action.key}") for action in self.actions}
        self.on_time = {task.id: terms.bool(f"on_time_{task.id}") for task in problem.tasks}
        self.robots_of = {
            task.id: range(len(robots)) if self.carrier[task.id] is None
            else (self.carrier[task.id],)
            for task in problem.tasks
        }
        self.assigned = {
            (task.id, r): terms.bool(f"robot_{task.id}_{r}")
            for task in problem.tasks
            for r in self.robots_of[task.id]
        }
        self.earliest = {}
        self._add_tasks(travel, service)
        self.same = {}
        self.first = {}
        for k, (a, b) in enumerate(itertools.combinations(self.actions, 2)):
            if k % 1024 == 0:
                check_limit()
            if a.task != b.task and self._same_robot(a.task, b.task) is not False:
                self.first[a, b] = terms.bool(f"first_{a.key}_{b.key}")
                self._add_order(a, b, travel, service)
        self._add_capacity(check_limit)
        self._add_releases(travel, service, check_limit)
        self._break_symmetries()
        self._bound_on_time_per_robot(travel, service)

    def location(self, action: Action) -> int:
        return self.problem.location(action)

    def _add(self, *constraints: z3.BoolRef):
        """Asserts ``constraints`` in order, and lets go of them last first, as
        ``z3.Solver.add`` does (the order z3 frees terms in decides the numbers it reuses)."""
        for k in range(len(constraints)):
            z3.Z3_solver_assert(self.terms.ref, self.solver.solver, constraints[k].ast)

    def _add_tasks(self, travel, service):
        problem, terms = self.problem, self.terms
        for task in problem.tasks:
            drop = self.time[Action(task.id, DROPOFF)]
            carrier = self.carrier[task.id]
            if carrier is None:
                choices = [self.assigned[task.id, r] for r in self.robots_of[task.id]]
                self._add(terms.pb_equal([(choice, 1) for choice in choices], 1))
                pick = self.time[Action(task.id, PICKUP)]
                for r, robot in enumerate(problem.robots):
                    arrive = robot.ready_time + travel[robot.location, task.pickup] + service
                    self._add(terms.implies(self.assigned[task.id, r],
                                            terms.at_least(pick, arrive)))
                    if arrive + travel[task.pickup, task.dropoff] + service > task.deadline:
                        self._add(terms.any(terms.negation(self.assigned[task.id, r]),
                                            terms.negation(self.on_time[task.id])))
                soonest = earliest_pickup(problem, task)
                leg = float(travel[task.pickup, task.dropoff] + service)
                self._add(terms.at_least(pick, soonest),
                          terms.at_least(drop, terms.plus(pick, leg)))
                self.earliest[Action(task.id, PICKUP)] = soonest
                self.earliest[Action(task.id, DROPOFF)] = soonest + leg
            else:
                robot = problem.robots[carrier]
                arrive = robot.ready_time + travel[robot.location, task.dropoff] + service
                self._add(self.assigned[task.id, carrier], terms.at_least(drop, arrive))
                self.earliest[Action(task.id, DROPOFF)] = arrive
            self._add(terms.implies(self.on_time[task.id], terms.at_most(drop, task.deadline)))

    def _same_robot(self, i: int, j: int):
        """True, False or a Boolean saying tasks ``i`` and ``j`` are done by one robot."""
        key = (min(i, j), max(i, j))
        if key in self.same:
            return self.same[key]
        carrier_i, carrier_j = self.carrier[i], self.carrier[j]
        if carrier_i is not None and carrier_j is not None:
            same = carrier_i == carrier_j
        elif carrier_i is not None:
            same = self.assigned[j, carrier_i]
        elif carrier_j is not None:
            same = self.assigned[i, carrier_j]
        else:
            terms = self.terms
            same = terms.bool(f"same_{key[0]}_{key[1]}")
            for r in range(len(self.problem.robots)):
                on_i, on_j = self.assigned[i, r], self.assigned[j, r]
                self._add(terms.any(terms.negation(on_i), terms.negation(on_j), same))
                self._add(terms.any(terms.negation(same), terms.negation(on_i), on_j))
        self.same[key] = same
        return same

    def before(self, a: Action, b: Action):
        """The literal for ``a`` before ``b`` on their (shared) robot."""
        if a.task == b.task:
            return self.terms.value(a.kind == PICKUP)
        if (a, b) in self.first:
            return self.first[a, b]
        return self.terms.negation(self.first[b, a])

    def _add_order(self, a: Action, b: Action, travel, service):
        terms = self.terms
        same = self._same_robot(a.task, b.task)
        guard = [] if same is True else [terms.negation(same)]
        order = self.first[a, b]
        for x, y, x_first in ((a, b, order), (b, a, terms.negation(order))):
            leg = float(travel[self.location(x), self.location(y)] + service)
            self._add(terms.any(*guard, terms.negation(x_first),
                                terms.at_least(self.time[y], terms.plus(self.time[x], leg))))

    def _add_capacity(self, check_limit: Callable[[], None]):
        """At each pickup the items on board (itself included) fit the robot."""
        problem, terms = self.problem, self.terms
        for pickup in self.actions:
            if pickup.kind != PICKUP:
                continue
            check_limit()
            on_board = []
            for other in problem.tasks:
                if other.id == pickup.task or not self._shares(pickup.task, other.id):
                    continue
                drop = Action(other.id, DROPOFF)
                aboard = terms.bool(f"aboard_{other.id}_at_{pickup.key}")
                condition = [self._same_robot(pickup.task, other.id), self.before(pickup, drop)]
                if self.carrier[other.id] is None:
                    condition.append(self.before(Action(other.id, PICKUP), pickup))
                self._add(terms.any(*[terms.negation(c) for c in condition], aboard))
                on_board.append(aboard)
            if not on_board:
                continue
            for capacity in sorted({robot.capacity for robot in problem.robots}):
                users = [
                    self.assigned[pickup.task, r]
                    for r, robot in enumerate(problem.robots)
                    if robot.capacity == capacity
                ]
                self._add(terms.implies(terms.any(*users),
                                        terms.count_at_most(on_board, capacity - 1)))

    def _shares(self, i: int, j: int) -> bool:
        return self._same_robot(i, j) is not False

    def _add_releases(self, travel, service, check_limit: Callable[[], None]):
        """A pickup released after some robot is ready may wait for its release at the
        previous location: bound its time by the leg from its immediate predecessor."""
        problem, terms = self.problem, self.terms
        soonest = min(robot.ready_time for robot in problem.robots)
        for task in problem.tasks:
            pickup = Action(task.id, PICKUP)
            if pickup not in self.time or task.release <= soonest:
                continue
            check_limit()
            others = [a for a in self.actions if a.task != task.id and self._shares(
                a.task, task.id)]
            for r in self.robots_of[task.id]:
                robot = problem.robots[r]
                alone = [terms.negation(terms.all(self._on_robot(c, r), self.before(c, pickup)))
                         for c in others]
                leg = float(travel[robot.location, task.pickup] + service)
                self._add(terms.implies(terms.all(self.assigned[task.id, r], *alone),
                                        terms.at_least(self.time[pickup], task.release + leg)))
            for a in others:
                between = [
                    terms.negation(terms.all(self._same_robot(c.task, task.id),
                                             self.before(a, c), self.before(c, pickup)))
                    for c in others if c != a and self._shares(a.task, c.task)
                ]
                leg = float(travel[self.location(a), task.pickup] + service)
                self._add(terms.implies(
                    terms.all(self._same_robot(a.task, task.id), self.before(a, pickup),
                              *between),
                    terms.at_least(self.time[pickup], task.release + leg),
                ))

    def _on_robot(self, action: Action, r: int):
        if self.carrier[action.task] is not None:
            return self.terms.value(self.carrier[action.task] == r)
        return self.assigned[action.task, r]

    def _break_symmetries(self):
        """Interchangeable robots take tasks in id order (each one's lowest task id is
        below the next one's); interchangeable tasks are picked up in id order."""
        problem, terms = self.problem, self.terms
        open_tasks = [task.id for task in problem.tasks if self.carrier[task.id] is None]
        classes = {}
        for r, robot in enumerate(problem.robots):
            if not robot.carrying:
                signature = (robot.location, robot.ready_time, robot.capacity)
                classes.setdefault(signature, []).append(r)
        for members in classes.values():
            for r, s in zip(members, members[1:], strict=False):
                for k, task in enumerate(open_tasks):
                    earlier = [self.assigned[t, r] for t in open_tasks[:k]]
                    self._add(terms.implies(self.assigned[task, s], terms.any(*earlier)))
        twins = {}
        for task in problem.tasks:
            if self.carrier[task.id] is None:
                signature = (task.pickup, task.dropoff, task.deadline, task.release)
                twins.setdefault(signature, []).append(task.id)
        for members in twins.values():
            for i, j in zip(members, members[1:], strict=False):
                # Twins are interchangeable only while their deadlines are asserted alike.
                self._add(terms.implies(
                    terms.equal(self.on_time[i], self.on_time[j]),
                    terms.at_most(self.time[Action(i, PICKUP)], self.time[Action(j, PICKUP)]),
                ))

    def _bound_on_time_per_robot(self, travel, service):
        """How many tasks a robot can finish on time, by each deadline ``D``: an item is on
        board from its pickup's completion to its drop-off's, at least ``d(p, q) + s``, and
        at most ``κ`` items are on board at once, all within ``[ρ + reach, D]`` (``reach``:
        the robot's shortest drive to a pickup plus ``s``). So the open tasks with deadlines
        up to ``D`` that robot ``r`` does on time have ``Σ (d(p, q) + s) <= κ (D - ρ -
        reach)``; ``done[i, r]`` stands for "on robot ``r`` and on time". Each bound that
        can cut anything is added and kept in ``robot_bounds`` as (robot, number of tasks by
        deadline, room in s)."""
        problem, terms = self.problem, self.terms
        self.robot_bounds = []
        open_tasks = sorted((task for task in problem.tasks if self.carrier[task.id] is None),
                            key=lambda task: (task.deadline, task.id))
        if not open_tasks:
            return
        weights = [int(travel[task.pickup, task.dropoff] + service) for task in open_tasks]
        for r, robot in enumerate(problem.robots):
            reach = min(travel[robot.location, task.pickup] for task in open_tasks) + service
            bounds, seen = [], 0
            for k, (task, weight) in enumerate(zip(open_tasks, weights, strict=True)):
                seen += weight
                room = robot.capacity * (task.deadline - robot.ready_time - reach)
                last = k + 1 == len(open_tasks) or open_tasks[k + 1].deadline > task.deadline
                if last and seen > room:
                    bounds.append((k + 1, max(0, math.floor(room))))
            if not bounds:
                continue
            done = []
            for task, weight in zip(open_tasks[:bounds[-1][0]], weights, strict=False):
                literal = terms.bool(f"done_{task.id}_{r}")
                self._add(terms.any(terms.negation(self.assigned[task.id, r]),
                                    terms.negation(self.on_time[task.id]), literal))
                done.append((literal, weight))
            for count, room in bounds:
                self._add(terms.pb_at_most(done[:count], room))
                self.robot_bounds.append((r, count, room))

    def routes(self, model: z3.ModelRef) -> tuple[tuple[Action, ...], ...]:
        """The routes of a model: each robot's actions in order of their model times."""
        routes = [[] for _ in self.problem.robots]
        for (task, r), literal in self.assigned.items():
            if z3.is_true(model.eval(literal, True)):
                for action in self.actions:
                    if action.task == task:
                        routes[r].append(action)
        times = {a: float(model.eval(self.time[a], True).as_fraction()) for a in self.actions}
        return tuple(tuple(sorted(route, key=lambda a: times[a])) for route in routes)

    def hint(self, allocation: Allocation):
        """Prefer the assignments and orders of ``allocation`` in the search."""
        prefer, times = self.terms.prefer, {}
        for r, (route, route_times) in enumerate(
            zip(allocation.routes, allocation.times, strict=True)
        ):
            for action, time in zip(route, route_times, strict=True):
                times[action] = time
                prefer(self.solver, self.assigned[action.task, r], True)
        for (a, b), literal in self.first.items():
            prefer(self.solver, literal, times[a] < times[b])


class _Solve:
    """One allocation, in a z3 context of its own (so the answer depends only on the problem
    and the parameters): feasibility, then the objective or the fallback, within the budget
    (and the time limit, when one is set)."""

    def __init__(self, problem: AllocationProblem, params: SmtAllocatorParams):
        self.problem = problem
        self.params = params
        self.limit = _Limit(params.budget, _stop_time(params.time_limit))
        self._solver = None
        self._encoding = None
        self._bounds = 0

    @property
    def solver(self) -> z3.Solver:
        """The allocation's solver, in a new z3 context (made on first use: a greedy answer
        may need none)."""
        if self._solver is None:
            self._solver = z3.SimpleSolver(ctx=z3.Context())
            self._solver.set("random_seed", self.params.random_seed)
        return self._solver

    @property
    def context(self) -> z3.Context:
        return self.solver.ctx

    @property
    def encoding(self) -> _Encoding:
        if self._encoding is None:
            self._encoding = _Encoding(self.problem, self.solver, self._check_limit)
        return self._encoding

    def run(self) -> Allocation:
        """The allocation, with the z3 work spent on it (resource units)."""
        if not self.problem.tasks:
            return Allocation.of(self.problem, [() for _ in self.problem.robots], optimal=True)
        greedy = best_heuristic(self.problem) if self.params.greedy_start else None
        try:
            allocation = self._solve(greedy)
        except _OutOfBudget:
            allocation = self._cut_short(greedy, "while building the encoding")
        return _replace(allocation, work=self._spent())

    def _spent(self) -> int:
        """z3 resource units counted so far in this allocation's context."""
        if self._solver is None:
            return 0
        return int(self._solver.statistics().get_key_value("rlimit count"))

    def _out_of(self, limit: _Limit) -> str | None:
        """``"time limit"`` or ``"budget"`` when that part of ``limit`` has run out, else
        None."""
        if limit.stop_time is not None and wallclock.perf_counter() >= limit.stop_time:
            return "time limit"
        if self._spent() >= limit.units:
            return "budget"
        return None

    def _check_limit(self):
        if self._out_of(self.limit) is not None:
            raise _OutOfBudget

    def _ran_out(self, when: str) -> str:
        """The note for an answer cut short ``when``: which limit ran out."""
        return f"{self._out_of(self.limit) or 'budget'} ran out {when}"

    def _cut_short(self, greedy: Allocation | None, when: str) -> Allocation:
        greedy = greedy or best_heuristic(self.problem)
        status = FEASIBLE if not greedy.late_tasks else UNKNOWN
        return _replace(greedy, status=status, optimal=False, note=self._ran_out(when))

    def _solve(self, greedy: Allocation | None) -> Allocation:
        if greedy is not None and not greedy.late_tasks:
            best, optimal = self._optimize_objective(greedy)
            return _replace(best, status=FEASIBLE, optimal=optimal,
                            note="" if optimal else self._ran_out("before the optimum"))
        if greedy is not None:
            self.encoding.hint(greedy)
        result = self._check(list(self.encoding.on_time.values()))
        if result == z3.sat:
            best, optimal = self._optimize_objective(self._allocation())
            return _replace(best, status=FEASIBLE, optimal=optimal,
                            note="" if optimal else self._ran_out("before the optimum"))
        if result == z3.unknown:
            return self._cut_short(greedy, "before the solver answered")
        greedy = greedy or best_heuristic(self.problem)
        conflict = self._minimal_conflict()
        best, most, assumptions = self._most_on_time(greedy)
        best, least = self._least_tardiness(best, assumptions)
        note = "" if most and least else self._ran_out("before the fallback was proven best")
        return _replace(best, status=INFEASIBLE, conflict=conflict, optimal=most and least,
                        note=note)

    def _minimal_conflict(self) -> tuple[int, ...]:
        """The tasks of the last unsat core, made minimal by deletion while a quarter of the
        budget (and of the time limit) lasts (then possibly not minimal)."""
        task_of = {literal.get_id(): task for task, literal in self.encoding.on_time.items()}
        core = [literal for literal in self.solver.unsat_core()]
        limit = self._share(CORE_SHARE)
        k = 0
        while k < len(core):
            trial = core[:k] + core[k + 1 :]
            result = self._check(trial, limit)
            if result == z3.unsat:
                smaller = {literal.get_id() for literal in self.solver.unsat_core()}
                core = [literal for literal in trial if literal.get_id() in smaller]
            elif result == z3.sat:
                k += 1
            else:
                break
        return tuple(sorted(task_of[literal.get_id()] for literal in core))

    def _share(self, fraction: float) -> _Limit:
        """The limit ``fraction`` of the budget (and of the time limit) from now on, within
        the allocation's."""
        units = min(self.limit.units, self._spent() + int(fraction * self.params.budget))
        if self.limit.stop_time is None:
            return _Limit(units)
        seconds = fraction * self.params.time_limit
        return _Limit(units, min(self.limit.stop_time, wallclock.perf_counter() + seconds))

    def _check(self, assumptions, limit: _Limit | None = None) -> z3.CheckSatResult:
        """``solver.check`` with what is left of ``limit`` (default: the allocation's);
        ``unknown`` when nothing is."""
        limit = limit or self.limit
        units = limit.units - self._spent()
        if units <= 0:
            return z3.unknown
        self.solver.set("rlimit", units)
        if limit.stop_time is not None:
            seconds = limit.stop_time - wallclock.perf_counter()
            if seconds <= 0:
                return z3.unknown
            self.solver.set("timeout", max(1, int(seconds * 1000)))
        return self.solver.check(*assumptions)

    def _allocation(self) -> Allocation:
        return Allocation.of(self.problem, self.encoding.routes(self.solver.model()))

    def _bound_literal(self, constraint) -> z3.BoolRef:
        self._bounds += 1
        literal = z3.Bool(f"bound_{self._bounds}", self.context)
        self.solver.add(z3.Implies(literal, constraint))
        return literal

    def _tighten(self, best, value_of, term, lower, assumptions, polish=None):
        """Search on ``term <= bound`` until ``value_of(best)`` is within the gap of the
        optimum. Returns the best allocation and whether it is proven within the gap.
        ``polish`` (optional) improves each allocation the solver finds, never raising
        ``value_of``; the solver is then hinted with the polished one.

        Each bound asks for a tenth of the remaining range (at least half the gap): easy
        improvements come first, so an answer cut short by the time limit is still good."""
        value = value_of(best)
        lower -= 1e-9  # the optimum is > lower
        while value - lower > self.params.objective_gap:
            bound = value - max(TIGHTEN_STEP * (value - lower), self.params.objective_gap / 2)
            result = self._check([*assumptions, self._bound_literal(term <= bound)])
            if result == z3.sat:
                best = self._allocation()
                if polish is not None:
                    best = polish(best)
                    self.encoding.hint(best)
                value = value_of(best)
                if value > bound + 1e-6:
                    raise RuntimeError(f"the schedule ({value}) breaks the bound ({bound})")
            elif result == z3.unsat:
                lower = bound
            else:
                return best, False
        return best, True

    def _optimize_objective(self, best: Allocation):
        objective = self.params.objective
        if objective == "none":
            return best, True
        encoding = self.encoding
        encoding.hint(best)
        on_time = list(encoding.on_time.values())
        times = [encoding.time[action] for action in encoding.actions]
        if objective == "makespan":
            makespan = z3.Real("makespan", self.context)
            for time in times:
                self.solver.add(makespan >= time)
            lower = max(encoding.earliest.values())
            return self._tighten(best, Allocation.makespan, makespan, lower, on_time)
        drops = [action for action in encoding.actions if action.kind == DROPOFF]
        total = z3.Sum([encoding.time[action] for action in drops])
        lower = sum(encoding.earliest[action] for action in drops)
        return self._tighten(best, _total_drop_time, total, lower, on_time)

    def _most_on_time(self, best: Allocation):
        """Linear search upwards on the number of tasks on time, starting from ``best``,
        each answer improved by local search. The tasks that can be on time alone bound the
        count: ``best`` reaching it is proven without a search. Returns the best allocation,
        whether it is proven to have the most tasks on time, and assumptions that keep at
        least that many on time."""
        encoding, tasks = self.encoding, self.problem.tasks
        hopeful = [
            encoding.on_time[task.id] for task in tasks
            if encoding.earliest[Action(task.id, DROPOFF)] <= task.deadline
        ]
        if len(tasks) - len(best.late_tasks) >= len(hopeful):
            return best, True, hopeful
        result = self._check(hopeful)
        if result == z3.sat:
            return self._allocation(), True, hopeful
        proven = result == z3.unsat
        while proven and len(tasks) - len(best.late_tasks) < len(hopeful) - 1:
            wanted = len(tasks) - len(best.late_tasks) + 1
            result = self._check([self._bound_literal(z3.AtLeast(*hopeful, wanted))])
            proven = result != z3.unknown
            if result != z3.sat:
                break
            best = improve(self.problem, self._allocation())
        on_time = len(tasks) - len(best.late_tasks)
        if on_time == 0:
            return best, proven, []
        return best, proven, [self._bound_literal(z3.AtLeast(*hopeful, on_time))]

    def _least_tardiness(self, best: Allocation, assumptions):
        """Among allocations with as many tasks on time as ``best`` (``assumptions``), the
        one with the least total tardiness (the late tasks as early as possible)."""
        encoding, tardiness, lower = self.encoding, [], 0.0
        for task in self.problem.tasks:
            drop = Action(task.id, DROPOFF)
            late_by = z3.Real(f"late_{task.id}", self.context)
            self.solver.add(late_by >= 0, late_by >= encoding.time[drop] - task.deadline)
            tardiness.append(late_by)
            lower += max(0.0, encoding.earliest[drop] - task.deadline)
        best = self._polish(best)
        encoding.hint(best)
        return self._tighten(best, self._tardiness_of, z3.Sum(tardiness), lower, assumptions,
                             self._polish)

    def _polish(self, allocation: Allocation) -> Allocation:
        """``allocation`` improved by local search, if that keeps as many tasks on time
        (then the total tardiness is no higher)."""
        improved = improve(self.problem, allocation)
        if len(improved.late_tasks) == len(allocation.late_tasks):
            return improved
        return allocation

    def _tardiness_of(self, allocation: Allocation) -> float:
        return allocation.total_tardiness(self.problem)


def best_heuristic(problem: AllocationProblem) -> Allocation:
    """The greedy allocation, improved by local search when it has late tasks (an allocation
    with every task on time is kept as it is)."""
    greedy = GreedyAllocator().allocate(problem)
    return improve(problem, greedy) if greedy.late_tasks else greedy


def _stop_time(seconds: float | None) -> float | None:
    """The ``time.perf_counter`` reading ``seconds`` from now (None: no time limit)."""
    return None if seconds is None else wallclock.perf_counter() + seconds


def _total_drop_time(allocation: Allocation) -> float:
    return sum(allocation.drop_times().values())


def _replace(allocation: Allocation, **changes) -> Allocation:
    return Allocation(**dict(allocation.__dict__, **changes))
