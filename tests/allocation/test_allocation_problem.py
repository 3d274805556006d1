"""The allocation problem: input checks, timing, and the online helpers."""

import numpy as np
import pytest

from mrta_drake.allocation import (
    Action,
    AllocationProblem,
    RobotStart,
    RobotStatus,
    Task,
    committed_start,
)
from mrta_drake.allocation.problem import check_stream, keeping_planned, stream_tasks
from mrta_drake.errors import InputError
from mrta_drake.payloads import DROPOFF, PICKUP
from mrta_drake.scenario.schema import TaskBatch, TaskConfig

TRAVEL = np.array([[0, 5, 30], [5, 0, 5], [30, 5, 0]])


def test_travel_becomes_shortest_over_stops():
    problem = AllocationProblem(TRAVEL, (RobotStart("a", 0),), ())
    assert problem.travel[0, 2] == 10  # via location 1
    assert not problem.travel.flags.writeable


def test_completion_times_wait_for_the_release():
    problem = AllocationProblem(TRAVEL, (RobotStart("a", 0, ready_time=2.0),),
                                (Task(0, 1, 2, 100.0, release=20.0),))
    route = (Action(0, PICKUP), Action(0, DROPOFF))
    assert problem.completion_times(0, route) == (26.0, 32.0)


@pytest.mark.parametrize("make, field, words", [
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 3),), ()), "robots[0].location",
     "unknown location id 3"),
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 0),), (Task(0, 0, 7, 50.0),)),
     "tasks[0].dropoff", "unknown location id 7"),
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 0),), (Task(0, 0, 1, 5.0, 10.0),)),
     "tasks[0].deadline", "is not after the release 10"),
    (lambda: AllocationProblem(-TRAVEL, (RobotStart("a", 0),), ()), "travel", ">= 0"),
    (lambda: AllocationProblem(TRAVEL[:2], (RobotStart("a", 0),), ()), "travel", "square"),
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 0, capacity=0),), ()),
     "robots[0].capacity", ">= 1"),
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 0, capacity=1, carrying=(0, 1)),),
                               (Task(0, 0, 1, 50.0), Task(1, 0, 1, 50.0))),
     "robots[0].carrying", "exceed the capacity"),
    (lambda: AllocationProblem(TRAVEL, (RobotStart("a", 0, planned=(Action(0, DROPOFF),)),),
                               (Task(0, 0, 1, 50.0),)),
     "robots[0].planned", "before the item is on board"),
])
def test_bad_input_names_the_field(make, field, words):
    with pytest.raises(InputError) as error:
        make()
    assert error.value.field == field
    assert words in str(error.value) and "\n" not in str(error.value)


def test_keeping_planned_starts_after_the_planned_actions():
    problem = AllocationProblem(
        TRAVEL, (RobotStart("a", 0, carrying=(0,), planned=(Action(1, PICKUP),
                                                            Action(1, DROPOFF))),),
        (Task(0, 0, 2, 100.0), Task(1, 1, 2, 100.0), Task(2, 2, 0, 100.0)),
    )
    rest = keeping_planned(problem)
    assert [task.id for task in rest.tasks] == [0, 2]
    assert rest.robots[0] == RobotStart("a", 2, 12.0, carrying=(0,))


def test_committed_start_finishes_the_current_leg_and_never_starts_before_now():
    tasks = {0: Task(0, 1, 2, 100.0), 1: Task(1, 0, 1, 100.0, release=30.0)}
    driving = RobotStatus("a", 1, 10.0, carrying=(0,), current=Action(0, DROPOFF))
    assert committed_start(driving, 12.0, tasks, TRAVEL, 1.0) == RobotStart("a", 2, 16.0)
    assert committed_start(driving, 40.0, tasks, TRAVEL, 1.0).ready_time == 40.0
    fetching = RobotStatus("a", 0, 0.0, current=Action(1, PICKUP))
    start = committed_start(fetching, 31.0, tasks, TRAVEL, 1.0)
    assert (start.location, start.ready_time, start.carrying) == (0, 31.0, (1,))


def test_task_stream():
    stream = (TaskBatch(0.0, [TaskConfig(0, 1, 50.0)]),
              TaskBatch(40.0, [TaskConfig(2, 0, 150.0), TaskConfig(1, 2, 300.0)]))
    check_stream(stream, 3)
    assert stream_tasks(stream)[1] == (Task(1, 2, 0, 150.0, 40.0), Task(2, 1, 2, 300.0, 40.0))


@pytest.mark.parametrize("stream, field", [
    ((TaskBatch(10.0, [TaskConfig(0, 5, 50.0)]),), "tasks_stream[0].tasks[0].dropoff"),
    ((TaskBatch(60.0, [TaskConfig(0, 1, 50.0)]),), "tasks_stream[0].tasks[0].deadline"),
    ((TaskBatch(10.0), TaskBatch(5.0)), "tasks_stream[1].arrival"),
])
def test_bad_streams(stream, field):
    with pytest.raises(InputError) as error:
        check_stream(stream, 3, "tasks.json")
    assert error.value.field == field and str(error.value).startswith("tasks.json: ")
