"""TaskAllocator in a Drake simulation, with fake robots that do their stops on time (or
late by a fixed delay) and report their progress."""

from dataclasses import replace

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake.allocation import FEASIBLE, INFEASIBLE, GreedyAllocator, SmtAllocator
from mrta_drake.allocation.feedback_params import OPEN_LOOP
from mrta_drake.allocation.task_allocator import AllocationEvent, ReplanEvent, TaskAllocator
from mrta_drake.errors import InputError
from mrta_drake.payloads import FleetPlan, RobotProgress, Visit
from mrta_drake.scenario.schema import TaskBatch, TaskConfig

TRAVEL = 10 * np.abs(np.subtract.outer(np.arange(5), np.arange(5)))


class FakeRobot(LeafSystem):
    """Does the stops of its plan in order, each taking travel + 1 s + ``delay`` s."""

    def __init__(self, index: int, name: str, start: int, delay: float = 0.0):
        super().__init__()
        self._index, self._delay = index, delay
        self._plan = self.DeclareAbstractInputPort("plan", AbstractValue.Make(FleetPlan(())))
        initial = (RobotProgress(robot=name, last_location=start), 0.0, 0.0)
        self._state = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclareAbstractOutputPort(
            "progress", lambda: AbstractValue.Make(initial[0]),
            lambda context, output: output.set_value(self._progress(context)[0]),
            prerequisites_of_calc={self.abstract_state_ticket(self._state)},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(0.1, 0.0, self._update)

    def _progress(self, context):
        return context.get_abstract_state(self._state).get_value()

    def _update(self, context, state):
        (progress, finish, began), now = self._progress(context), context.get_time()
        stop = progress.current_stop
        if stop is not None and now >= finish:
            visit = Visit(stop.key, stop.location, finish, stop.task, stop.action, began)
            progress = RobotProgress(progress.robot, (*progress.visits, visit), stop.location)
        if progress.current_stop is None:
            done = {visit.key for visit in progress.visits}
            plans = self._plan.Eval(context).plans
            stops = plans[self._index].stops if plans else ()
            stop = next((s for s in stops if s.key not in done), None)
            if stop is not None:
                finish = now + TRAVEL[progress.last_location, stop.location] + 1.0 + self._delay
                began = now
                progress = RobotProgress(progress.robot, progress.visits,
                                         progress.last_location, stop)
        state.get_mutable_abstract_state(self._state).set_value((progress, finish, began))


def simulate(stream, starts, allocator, delay=0.0, feedback=OPEN_LOOP):
    builder = DiagramBuilder()
    names = [f"robot{k}" for k in range(len(starts))]
    allocator_system = builder.AddSystem(
        TaskAllocator(stream, names, starts, [2] * len(starts), TRAVEL, allocator, rate_hz=1.0,
                      feedback=feedback))
    robots = []
    for k, (name, start) in enumerate(zip(names, starts, strict=True)):
        robot = builder.AddSystem(FakeRobot(k, name, start, delay))
        builder.Connect(allocator_system.GetOutputPort("plan"), robot.GetInputPort("plan"))
        builder.Connect(robot.GetOutputPort("progress"),
                        allocator_system.get_progress_input_port(k))
        robots.append(robot)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()

    def output(system, port):
        return system.GetOutputPort(port).Eval(system.GetMyContextFromRoot(context))

    return simulator, lambda port: output(allocator_system, port), \
        lambda k: output(robots[k], "progress")


def planned_tasks(plan):
    return sorted(stop.task for robot in plan.plans for stop in robot.stops)


def test_plans_appear_on_arrival_and_are_redone_on_the_next_batch():
    stream = (TaskBatch(2.0, (TaskConfig(1, 2, 100.0),)),
              TaskBatch(20.0, (TaskConfig(3, 0, 200.0),)))
    simulator, allocator, progress = simulate(stream, [0, 4], SmtAllocator())
    simulator.AdvanceTo(1.5)
    assert allocator("plan").revision == 0 and planned_tasks(allocator("plan")) == []
    simulator.AdvanceTo(2.5)
    first = allocator("plan")
    assert first.revision == 1 and planned_tasks(first) == [0, 0]
    simulator.AdvanceTo(20.5)
    second = allocator("plan")
    events = allocator("events")
    assert second.revision == 2 and [event.batches for event in events] == [(0,), (1,)]
    assert all(event.status == FEASIBLE for event in events)
    # Robot 0 picked task 0 up at 13.1 s and is driving to drop it: that leg is kept.
    assert progress(0).current_stop.key == "t0/dropoff"
    kept = second.plans[0].stops[0]
    assert kept.key == "t0/dropoff" and kept.planned_time == pytest.approx(24.1)
    assert sorted(planned_tasks(second)) == [0, 1, 1]
    simulator.AdvanceTo(120.0)
    visits = {visit.key: visit.time for k in range(2) for visit in progress(k).visits}
    assert set(visits) == {"t0/pickup", "t0/dropoff", "t1/pickup", "t1/dropoff"}
    predicted = dict(events[-1].predicted)
    assert visits["t1/dropoff"] == pytest.approx(predicted[1], abs=0.2)
    assert visits["t1/dropoff"] <= 200.0


@pytest.mark.parametrize("delay, status, late", [(0.0, FEASIBLE, ()), (30.0, INFEASIBLE, (1,))])
def test_measured_delays_make_a_new_task_late(delay, status, late):
    # Task 1 (1 -> 2, due 50 s) arrives at 35 s. On time, the robot is idle at 1 and drops it
    # at 47 s; 30 s late on every stop, it is still driving task 0's drop-off (leg started at
    # 31 s) and could drop task 1 at 54 s at best.
    stream = (TaskBatch(0.0, (TaskConfig(0, 1, 500.0),)),
              TaskBatch(35.0, (TaskConfig(1, 2, 50.0),)))
    simulator, allocator, _ = simulate(stream, [0], SmtAllocator(), delay)
    simulator.AdvanceTo(35.5)
    event = allocator("events")[-1]
    assert (event.status, event.late_tasks, event.conflict) == (status, late, late)
    assert dict(event.predicted)[1] == pytest.approx(47.0 if delay == 0 else 54.0, abs=0.2)


def test_unconnected_progress_means_robots_at_their_starts():
    allocator = TaskAllocator((TaskBatch(0.0, (TaskConfig(1, 2, 100.0),)),), ["a"], [0], [2],
                              TRAVEL, GreedyAllocator(), rate_hz=2.0)
    simulator = Simulator(allocator)
    simulator.AdvanceTo(1.0)
    plan = allocator.GetOutputPort("plan").Eval(simulator.get_context())
    assert [(stop.key, stop.planned_time) for stop in plan.plans[0].stops] == [
        ("t0/pickup", 11.0), ("t0/dropoff", 22.0)]


def test_bad_stream_is_an_input_error():
    with pytest.raises(InputError, match=r"tasks_stream\[0\].tasks\[0\].pickup"):
        TaskAllocator((TaskBatch(0.0, (TaskConfig(9, 2, 100.0),)),), ["a"], [0], [2],
                      TRAVEL, GreedyAllocator(), rate_hz=1.0)


@pytest.mark.parametrize("feedback, predicted", [
    (OPEN_LOOP, 72.0),
    (replace(OPEN_LOOP, learn_travel_times=True), 82.0),
    (replace(OPEN_LOOP, planning_margin=3.0), 75.0),
    (replace(OPEN_LOOP, learn_travel_times=True, planning_margin=3.0), 85.0),
])
def test_learned_travel_times_and_margins_change_what_is_planned(feedback, predicted):
    # Every stop takes 10 s longer than the matrix says: task 0's drop-off leg 0 -> 1 took
    # 20 s for 10 planned (ratio 2), so task 1's leg 1 -> 2, not driven yet, is planned at
    # 20 s with learning (the fleet-wide ratio); a margin adds to every leg.
    stream = (TaskBatch(0.0, (TaskConfig(0, 1, 500.0),)),
              TaskBatch(60.0, (TaskConfig(1, 2, 500.0),)))
    simulator, allocator, _ = simulate(stream, [0], GreedyAllocator(), 10.0, feedback)
    simulator.AdvanceTo(60.5)
    assert dict(allocator("events")[-1].predicted)[1] == pytest.approx(predicted, abs=0.2)


@pytest.mark.parametrize("deadline, reason, drifted", [
    (500.0, "drift: tasks 0, 1 (+9 s)", (0, 1)), (85.0, "late: task 1 (+9 s)", (1,))])
def test_a_robot_falling_behind_makes_a_replan_with_its_reason(deadline, reason, drifted):
    # Planned at 0 s: task 0 picked up at 1 s, task 1 dropped at 84 s. The pickup takes
    # 10 s more: from 6 s on, the drop-offs move by more than the 5 s margin (task 1's past
    # its deadline of 85 s), and 10 s after the last allocation the plan is redone.
    stream = (TaskBatch(0.0, (TaskConfig(0, 4, 500.0), TaskConfig(4, 0, deadline))),)
    feedback = replace(OPEN_LOOP, replan_on_delay=True, drift_margin=5.0, replan_interval=10.0)
    simulator, allocator, _ = simulate(stream, [0], GreedyAllocator(), 10.0, feedback)
    simulator.AdvanceTo(9.5)
    assert len(allocator("events")) == 1
    simulator.AdvanceTo(10.5)
    replan = allocator("events")[-1]
    assert isinstance(replan, ReplanEvent)
    assert (replan.time, replan.reason, replan.drifted, replan.batches) == (
        10.0, reason, drifted, ())


@pytest.mark.parametrize("starts, assignment, kept", [
    ([0], (("robot0", (1, 0)),), True),  # t1's pickup at 4 before t0's drop-off there
    ([0, 2], (("robot0", (0,)), ("robot1", (1,))), False)])
def test_a_replan_moves_tasks_only_to_have_fewer_late(starts, assignment, kept):
    # As above with task 0 due at 60 s, so that it is allocated first (earliest deadline)
    # and task 1 (due at 85 s) is chained behind it on robot 0, which then turns it late.
    # Alone, robot 0 can do no better than its route: the re-plan keeps it. With robot 1
    # idle at 2 (task 1 dropped at 72 s), the allocator's routes have no task late and are
    # taken.
    stream = (TaskBatch(0.0, (TaskConfig(0, 4, 60.0), TaskConfig(4, 0, 85.0))),)
    feedback = replace(OPEN_LOOP, replan_on_delay=True, drift_margin=5.0, replan_interval=10.0,
                       replan_only_if_fewer_late=True)
    simulator, allocator, _ = simulate(stream, starts, GreedyAllocator(), 10.0, feedback)
    simulator.AdvanceTo(10.5)
    first, replan = allocator("events")
    assert first.assignment[0] == ("robot0", (0, 1))
    assert isinstance(replan, ReplanEvent) and replan.assignment == assignment
    assert ("current routes kept" in replan.note) == kept
    assert replan.late_tasks == ((1,) if kept else ())


def test_a_drift_that_breaks_no_promise_retimes_the_plan():
    # As above with a loose deadline: at 7 s the overdue pickup (planned at 1 s) moves both
    # drop-offs 6 s later, more than the 5 s margin. The plan keeps its routes with the new
    # times at once (re-timing waits for no interval) and nothing is allocated again.
    stream = (TaskBatch(0.0, (TaskConfig(0, 4, 500.0), TaskConfig(4, 0, 500.0))),)
    feedback = replace(OPEN_LOOP, replan_on_delay=True, drift_margin=5.0, replan_interval=10.0,
                       retime_on_drift=True)
    simulator, allocator, _ = simulate(stream, [0], GreedyAllocator(), 10.0, feedback)
    simulator.AdvanceTo(6.5)
    before = allocator("plan")
    simulator.AdvanceTo(7.5)
    after = allocator("plan")
    assert after.revision == before.revision + 1
    assert [stop.key for stop in after.plans[0].stops] == [
        stop.key for stop in before.plans[0].stops]
    moved = [a.planned_time - b.planned_time
             for a, b in zip(after.plans[0].stops, before.plans[0].stops, strict=True)]
    assert moved == pytest.approx([6.0] * 4, abs=0.2)
    simulator.AdvanceTo(12.0)
    assert [type(event) for event in allocator("events")] == [AllocationEvent]


def test_the_open_loop_keeps_a_drifting_plan():
    stream = (TaskBatch(0.0, (TaskConfig(0, 4, 500.0), TaskConfig(4, 0, 90.0))),)
    simulator, allocator, _ = simulate(stream, [0], GreedyAllocator(), 10.0)
    simulator.AdvanceTo(100.0)
    assert [type(event) for event in allocator("events")] == [AllocationEvent]


@pytest.mark.parametrize("feedback, drops", [
    (OPEN_LOOP, {0: 43.0, 1: 54.0}),
    (replace(OPEN_LOOP, earliest_drop_offs=True), {0: 42.0, 1: 32.0})])
def test_earliest_drop_offs_hand_a_task_to_the_robot_that_drops_it_first(feedback, drops):
    # Robot 0 (at 0) takes task A (0 -> 4). Task B (4 -> 3) adds only 12 s to robot 0's
    # route (picked up on the way at 4, A dropped at 43 s, B at 54 s) but 32 s to idle robot
    # 1's (at 2: B dropped at 32 s), so cheapest insertion chains it behind A; the local
    # search hands it to robot 1 and A is dropped at 42 s.
    stream = (TaskBatch(0.0, (TaskConfig(0, 4, 100.0), TaskConfig(4, 3, 200.0))),)
    simulator, allocator, _ = simulate(stream, [0, 2], GreedyAllocator(), feedback=feedback)
    simulator.AdvanceTo(0.5)
    event = allocator("events")[-1]
    assert dict(event.predicted) == pytest.approx(drops)
    assert event.status == FEASIBLE
