"""TaskAllocator: the Drake block that turns a task stream into plans for the fleet.

When a batch of tasks arrives it freezes what each robot has done and the leg it is driving
(from the ``progress_<robot>`` inputs, with measured times), hands everything else to the
configured allocator, and outputs the new ``FleetPlan``. A robot breaking down (or being
repaired) is a reason to allocate again too, and so, with the feedback switches on
(``FeedbackParams``), is a plan drifting away from the robots' progress; it can plan with
travel times learned from the legs the robots complete. State changes only in its periodic
unrestricted update.
"""

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from mrta_drake.allocation.drift import DRIFT, find_drift
from mrta_drake.allocation.feedback_params import OPEN_LOOP, FeedbackParams
from mrta_drake.allocation.local_search import improve_keeping_verdict
from mrta_drake.allocation.problem import (
    UNKNOWN,
    Action,
    Allocation,
    AllocationProblem,
    RobotStart,
    RobotStatus,
    check_stream,
    committed_start,
    shortest_travel,
    stream_tasks,
)
from mrta_drake.allocation.travel_time_model import LearnedTravelTimes
from mrta_drake.allocation.verify import verify_allocation
from mrta_drake.errors import InputError
from mrta_drake.payloads import (
    DROPOFF,
    NO_DISTURBANCES,
    PICKUP,
    Disturbances,
    FleetPlan,
    RobotPlan,
    RobotProgress,
    Stop,
)


@dataclass(frozen=True)
class AllocationEvent:
    """One allocation the TaskAllocator made, at ``time`` (s), for the batches numbered
    ``batches`` (0-based in stream order).

    ``assignment`` pairs each robot name with the task ids of its new route (in order of
    their first action); ``predicted`` pairs each task id in those routes with its predicted
    drop-off time (s). ``late_tasks`` are predicted to miss their deadline; ``conflict`` is a
    set of tasks proven unable to all be on time (empty unless proven). ``status`` is the
    allocation's (``feasible``, ``infeasible`` or ``unknown``). ``solve_time`` is wall-clock
    seconds, the one field that differs between identical runs.

    Breakdowns: ``removed`` robots broke down since the last allocation and are out of the
    fleet (``returned`` ones were repaired and are back); ``lost_tasks`` are the tasks whose
    items the removed robots carried (they fail); ``reassigned`` the tasks the removed robots
    had planned that are now in other robots' routes.
    """

    time: float
    batches: tuple[int, ...]
    status: str
    assignment: tuple[tuple[str, tuple[int, ...]], ...]
    predicted: tuple[tuple[int, float], ...]
    late_tasks: tuple[int, ...] = ()
    conflict: tuple[int, ...] = ()
    solve_time: float = 0.0
    note: str = ""
    removed: tuple[str, ...] = ()
    returned: tuple[str, ...] = ()
    lost_tasks: tuple[int, ...] = ()
    reassigned: tuple[int, ...] = ()


@dataclass(frozen=True)
class ReplanEvent(AllocationEvent):
    """An allocation made between batches because the plan drifted (``FeedbackParams``
    ``replan_on_delay``): ``reason`` says how (``drift.Drift.reason``, e.g. ``"late: task 7
    (+14 s)"``), ``drifted`` the tasks whose drop-offs moved."""

    reason: str = ""
    drifted: tuple[int, ...] = ()


@dataclass(frozen=True)
class _State:
    """The TaskAllocator's abstract state: also the robots out of service (broken down) at
    the last allocation, the tasks whose items were lost, the travel times learned and how
    many of each robot's visits they were learned from. Immutable, so copies share it
    (Drake copies the state every update)."""

    next_batch: int
    plan: FleetPlan
    events: tuple[AllocationEvent, ...] = ()
    out: tuple[int, ...] = ()
    lost: tuple[int, ...] = ()
    learned: LearnedTravelTimes = LearnedTravelTimes()
    seen: tuple[int, ...] = ()

    def __deepcopy__(self, memo):
        return self


class TaskAllocator(LeafSystem):
    """Allocates a stream of task batches to a fleet as the batches arrive.

    .. pydrake_system::

        name: TaskAllocator
        input_ports:
        - progress_<robot>
        - disturbances (optional)
        output_ports:
        - plan
        - events

    Inputs: ``progress_<robot>`` (one per robot, ``RobotProgress``; an unconnected one means
    the robot has done nothing yet), ``disturbances`` (``Disturbances``). Outputs: ``plan``
    (``FleetPlan``) and ``events`` (a tuple of ``AllocationEvent``, oldest first).

    Breakdowns: at the first check after a robot breaks down it leaves the fleet: its plan
    is emptied, the items it carries are lost (their tasks are never allocated again) and
    everything else still open is allocated to the robots in service. A repaired robot
    rejoins at the first check after, planned from the location it last completed. With no
    robot in service nothing is allocated.

    Feedback (``feedback``, a ``FeedbackParams``; docs/allocation.md): with
    ``learn_travel_times`` every check learns from the legs completed since the last one
    and every allocation plans with the learned times (plus ``planning_margin``); with
    ``replan_on_delay`` a check with no batch or breakdown allocates again when
    ``drift.find_drift`` finds a drop-off turned late or moved by more than
    ``drift_margin``, at most ``replan_interval`` after the last allocation (a
    ``ReplanEvent``); with ``retime_on_drift`` a drift that turns nothing late only
    re-times the plan (same routes, times predicted now, no event); with
    ``replan_only_if_fewer_late`` a ``ReplanEvent`` keeps the robots' routes unless the
    allocator's have fewer tasks late; with ``earliest_drop_offs`` every allocation is
    improved by local search
    (``local_search.improve_keeping_verdict``, writing off tasks more than
    ``write_off_lateness`` late). Done and under-way actions are kept as for
    a batch.

    Args:
        stream: the task batches (``scenario_schema.TaskBatch`` or alike: ``arrival`` s,
            ``tasks`` with ``pickup``, ``dropoff``, ``deadline``), arrivals in order; task
            ids are numbered from 0 in stream order (see ``stream_tasks``).
        robot_names, start_locations, capacities: per robot, in scenario order (location
            ids; items carried at once).
        travel: (L, L) travel times between locations (s).
        allocator: any object with ``allocate(AllocationProblem) -> Allocation``, e.g. an
            ``SmtAllocator`` or a ``GreedyAllocator``.
        service_time: time for one pickup or drop-off (s).
        rate_hz: how often arrivals are checked (Hz); a batch is allocated at the first
            check at or after its arrival.
        feedback: the feedback switches; the default is the open loop (a block made from a
            scenario gets the scenario's allocator params, closed loop by default).
    """

    def __init__(
        self,
        stream: Sequence,
        robot_names: Sequence[str],
        start_locations: Sequence[int],
        capacities: Sequence[int],
        travel: np.ndarray,
        allocator,
        service_time: float = 1.0,
        *,
        rate_hz: float,
        source: str | None = None,
        feedback: FeedbackParams = OPEN_LOOP,
    ):
        super().__init__()
        if not len(robot_names) == len(start_locations) == len(capacities):
            raise InputError(source, "robots", f"{len(robot_names)} names, "
                             f"{len(start_locations)} start locations and {len(capacities)} "
                             "capacities")
        if not rate_hz > 0:
            raise InputError(source, "rate_hz", f"must be > 0 Hz, got {rate_hz}")
        fleet = tuple(
            RobotStart(name, location, 0.0, capacity)
            for name, location, capacity in zip(robot_names, start_locations, capacities,
                                                strict=True)
        )
        empty = AllocationProblem(travel, fleet, (), service_time, source)  # checks the input
        check_stream(stream, empty.num_locations, source)
        self._fleet = fleet
        self._travel = empty.travel
        self._service_time = service_time
        self._arrivals = tuple(float(batch.arrival) for batch in stream)
        self._batches = stream_tasks(stream)
        self._allocator = allocator
        self._source = source
        self._feedback = feedback
        self._model = feedback.travel_time_model(empty.travel)

        self._progress_ports = [
            self.DeclareAbstractInputPort(
                f"progress_{name}", AbstractValue.Make(RobotProgress(robot=name))
            )
            for name in robot_names
        ]
        initial = _State(
            next_batch=0,
            plan=FleetPlan(plans=tuple(RobotPlan(robot=name) for name in robot_names)),
            seen=(0,) * len(robot_names),
        )
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(initial))
        ticket = {self.abstract_state_ticket(self._state_index)}
        self.DeclareAbstractOutputPort(
            "plan", lambda: AbstractValue.Make(initial.plan),
            lambda context, output: output.set_value(self._state(context).plan),
            prerequisites_of_calc=ticket,
        )
        self.DeclareAbstractOutputPort(
            "events", lambda: AbstractValue.Make(()),
            lambda context, output: output.set_value(self._state(context).events),
            prerequisites_of_calc=ticket,
        )
        self._disturbances = self.DeclareAbstractInputPort(
            "disturbances", AbstractValue.Make(Disturbances()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def get_progress_input_port(self, robot: int):
        return self._progress_ports[robot]

    def _state(self, context) -> _State:
        return context.get_abstract_state(self._state_index).get_value()

    def _update(self, context, state):
        current = self._state(context)
        now = context.get_time()
        out = (self._disturbances.Eval(context) if self._disturbances.HasValue(context)
               else NO_DISTURBANCES).broken
        arrived = current.next_batch
        while arrived < len(self._arrivals) and self._arrivals[arrived] <= now:
            arrived += 1
        feedback = self._feedback
        progress = [self._progress(context, r) for r in range(len(self._fleet))]
        if feedback.learn_travel_times:
            current = self._learn(current, progress)
        released = [task for batch in self._batches[:arrived] for task in batch]
        drift = None
        if arrived == current.next_batch and out == current.out:
            may_replan = feedback.replan_on_delay and self._may_replan(current, now)
            if may_replan or (feedback.replan_on_delay and feedback.retime_on_drift):
                drift, problem, committed = self._drift(now, released, progress, current)
                if drift is not None and feedback.retime_on_drift and drift.kind == DRIFT:
                    current = dataclasses.replace(
                        current, plan=_retimed(current.plan, problem, committed, current.out))
                if drift is not None and (drift.kind == DRIFT and feedback.retime_on_drift
                                          or not may_replan):
                    drift = None
            if drift is None:
                if current is not self._state(context):
                    state.get_mutable_abstract_state(self._state_index).set_value(current)
                return
        travel = self._planning_travel(current)
        removed = [r for r in out if r not in current.out]
        done = {visit.key for robot in progress for visit in robot.visits}
        by_id = {task.id: task for task in released if task.id not in current.lost}
        newly_lost = tuple(sorted(
            task for r in removed
            for task in self._status(self._fleet[r], progress[r], done, by_id)[0].carrying))
        lost = current.lost + newly_lost
        problem, committed = self._problem(now, released, progress, current.plan, travel, out,
                                           lost)
        in_service = [r for r in range(len(self._fleet)) if r not in out]
        if in_service:
            allocation = self._allocator.allocate(problem)
            if feedback.earliest_drop_offs:
                allocation = improve_keeping_verdict(problem, allocation,
                                                     feedback.local_search())
            if drift is not None and feedback.replan_only_if_fewer_late:
                allocation = _kept_unless_fewer_late(problem, allocation)
        else:
            allocation = Allocation((), (), UNKNOWN, note="no robot in service")
        routes = dict(zip(in_service, range(len(in_service)), strict=True))
        plan = FleetPlan(
            plans=tuple(
                RobotPlan(robot=robot.name, stops=committed[r] + (
                    _stops(problem, allocation, routes[r]) if r in routes else ()))
                for r, robot in enumerate(self._fleet)
            ),
            revision=current.plan.revision + 1,
        )
        orphans = {stop.task for r in removed for stop in current.plan.plans[r].stops
                   if stop.task is not None and stop.task not in lost}
        event = _event(now, range(current.next_batch, arrived), problem, allocation)
        if drift is not None:
            event = ReplanEvent(**_fields(event), reason=drift.reason, drifted=drift.tasks)
        event = dataclasses.replace(
            event, removed=tuple(self._fleet[r].name for r in removed),
            returned=tuple(self._fleet[r].name for r in current.out if r not in out),
            lost_tasks=newly_lost,
            reassigned=tuple(sorted(orphans & {stop.task for p in plan.plans for stop in p.stops})))
        state.get_mutable_abstract_state(self._state_index).set_value(
            dataclasses.replace(current, next_batch=arrived, plan=plan,
                                events=(*current.events, event), out=out, lost=lost)
        )

    def _planning_travel(self, current: _State) -> np.ndarray:
        """The travel times (s) to plan with: the scenario's in the open loop."""
        feedback = self._feedback
        if not feedback.learn_travel_times and feedback.planning_margin == 0:
            return self._travel
        return shortest_travel(self._model.matrix(current.learned))

    def _learn(self, current: _State, progress: Sequence[RobotProgress]) -> _State:
        """``current`` having learned from every visit completed since it last learned: a
        leg from the robot's previous location (its start for the first visit) that took
        the time from setting off to completing, less the service time."""
        learned, seen = current.learned, list(current.seen)
        for r, report in enumerate(progress):
            visits = report.visits
            for k in range(seen[r], len(visits)):
                visit = visits[k]
                if visit.began is None:
                    continue
                origin = visits[k - 1].location if k else self._fleet[r].location
                learned = self._model.observe(learned, origin, visit.location,
                                              visit.time - visit.began - self._service_time)
            seen[r] = len(visits)
        if learned is current.learned and tuple(seen) == current.seen:
            return current
        return dataclasses.replace(current, learned=learned, seen=tuple(seen))

    def _may_replan(self, current: _State, now: float) -> bool:
        """Whether ``replan_interval`` has passed since the last allocation."""
        last = current.events[-1].time if current.events else -np.inf
        return now - last >= self._feedback.replan_interval

    def _drift(self, now, released, progress, current: _State):
        """The drift of the current plan at ``now`` (``drift.Drift``, or None), with the
        problem it was found in and each robot's committed stop (see ``_problem``)."""
        travel = self._planning_travel(current)
        problem, committed = self._problem(now, released, progress, current.plan, travel,
                                           current.out, current.lost)
        plans = [plan for r, plan in enumerate(current.plan.plans) if r not in current.out]
        return find_drift(problem, plans, self._feedback.drift_margin), problem, committed

    def _progress(self, context, r: int) -> RobotProgress:
        port = self._progress_ports[r]
        if not port.HasValue(context):
            return RobotProgress(robot=self._fleet[r].name)
        return port.Eval(context)

    def _problem(self, now, released, progress, previous: FleetPlan, travel, out=(), lost=()):
        """The problem to solve at ``now`` with ``travel`` times (s) for the robots not
        ``out`` of service, without the ``lost`` tasks, and each robot's committed stop (as
        a tuple; none when out)."""
        by_id = {task.id: task for task in released if task.id not in lost}
        done = {visit.key for robot in progress for visit in robot.visits}
        robots, committed, finishing = [], [], set()
        for r, (robot, report) in enumerate(zip(self._fleet, progress, strict=True)):
            if r in out:
                committed.append(())
                continue
            status, current = self._status(robot, report, done, by_id)
            planned = tuple(
                Action(stop.task, stop.action)
                for stop in previous.plans[r].stops
                if stop.key not in done and (current is None or stop.key != current.key)
                and stop.task in by_id
            )
            start = committed_start(status, now, by_id, travel, self._service_time, planned)
            robots.append(start)
            if current is None:
                committed.append(())
            else:
                committed.append((Stop(current.key, start.location, current.action,
                                       current.task, start.ready_time),))
                if current.action == DROPOFF:
                    finishing.add(current.task)
        open_tasks = tuple(
            task for task in by_id.values()
            if f"t{task.id}/{DROPOFF}" not in done and task.id not in finishing
        )
        problem = AllocationProblem(travel, tuple(robots), open_tasks,
                                    self._service_time, self._source)
        return problem, committed

    def _status(self, robot: RobotStart, report: RobotProgress, done, by_id):
        """The robot's ``RobotStatus`` and the task stop it is driving to (or None)."""
        location, time = robot.location, 0.0
        if report.last_location is not None:
            location = report.last_location
        on_board = []
        for visit in report.visits:
            location, time = visit.location, visit.time
            if visit.task in by_id and visit.action == PICKUP:
                on_board.append(visit.task)
            elif visit.task in on_board and visit.action == DROPOFF:
                on_board.remove(visit.task)
        stop = report.current_stop
        current = None
        if (stop is not None and stop.key not in done and stop.task in by_id
                and stop.action in (PICKUP, DROPOFF)):
            current = stop
        status = RobotStatus(
            name=robot.name, location=location, time=time, capacity=robot.capacity,
            carrying=tuple(on_board),
            current=None if current is None else Action(current.task, current.action),
        )
        return status, current


def _stops(problem: AllocationProblem, allocation: Allocation, r: int) -> tuple[Stop, ...]:
    return tuple(
        Stop(action.key, problem.location(action), action.kind, action.task, time)
        for action, time in zip(allocation.routes[r], allocation.times[r], strict=True)
    )


def _kept_unless_fewer_late(problem: AllocationProblem, allocation: Allocation) -> Allocation:
    """``allocation``, or the robots' current routes (their ``planned`` actions, re-timed)
    when those are a complete allocation of ``problem`` with no more tasks late."""
    kept = Allocation.of(problem, [robot.planned for robot in problem.robots],
                         note="re-planned: the current routes kept (no fewer tasks late)")
    if len(allocation.late_tasks) < len(kept.late_tasks) or verify_allocation(problem, kept):
        return allocation
    return kept


def _retimed(plan: FleetPlan, problem: AllocationProblem, committed, out) -> FleetPlan:
    """``plan`` with the same stops for every robot and the completion times ``problem``
    predicts now (its robots are those not ``out``, each with the rest of its plan as
    ``planned``; ``committed[r]``: robot ``r``'s committed stop, already re-predicted)."""
    in_service = iter(range(len(problem.robots)))
    plans = []
    for r, robot_plan in enumerate(plan.plans):
        if r in out:
            plans.append(robot_plan)
            continue
        i = next(in_service)
        route = problem.robots[i].planned
        rest = tuple(Stop(action.key, problem.location(action), action.kind, action.task, time)
                     for action, time in zip(route, problem.completion_times(i, route),
                                             strict=True))
        plans.append(dataclasses.replace(robot_plan, stops=committed[r] + rest))
    return FleetPlan(plans=tuple(plans), revision=plan.revision + 1)


def _fields(event) -> dict:
    return {f.name: getattr(event, f.name) for f in dataclasses.fields(event)}


def _event(now, batches, problem: AllocationProblem, allocation: Allocation) -> AllocationEvent:
    assignment = []
    for robot, route in zip(problem.robots, allocation.routes, strict=True):
        tasks = tuple(dict.fromkeys(action.task for action in route))
        assignment.append((robot.name, tasks))
    return AllocationEvent(
        time=now,
        batches=tuple(batches),
        status=allocation.status,
        assignment=tuple(assignment),
        predicted=tuple(sorted(allocation.drop_times().items())),
        late_tasks=allocation.late_tasks,
        conflict=allocation.conflict,
        solve_time=allocation.solve_time,
        note=allocation.note,
    )
