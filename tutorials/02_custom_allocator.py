"""Tutorial 2: write your own task allocator, swap it in, and compare it with the SMT one.

An allocator in mrta-drake is any object with ``allocate(problem) -> Allocation``
(``mrta_drake/allocation/``, docs/allocation.md). An ``AllocationProblem`` holds the travel
times between locations (whole seconds), each robot's start (``RobotStart``: location, ready
time, capacity, items on board, the rest of its previous plan) and the open tasks (``Task``:
pickup and drop-off location, release and deadline, s). The answer is a route of pickup and
drop-off ``Action``\\ s per robot; ``Allocation.of(problem, routes)`` computes the predicted
completion times and which tasks are late. ``verify_allocation`` checks any answer
independently (every task done once, pickup before drop-off by one robot, capacity, times).

Here we write ``EarliestPickupAllocator``, what a simple dispatcher does: tasks in order of
release, then deadline, each appended to the robot that can complete its pickup soonest. It
never looks at deadlines, nor carries two items at once. Then:

1. Offline: the scenario's whole task stream as one problem (as if every batch were known in
   advance; tasks still cannot start before their batch arrives), solved by both our
   allocator and ``SmtAllocator`` (z3: every task on time if at all possible, with a proof
   when not). Both answers are verified; the table shows who does what and what is late.
2. Online, in the simulation: ``task_allocator_block`` wraps our class in the ``TaskAllocator``
   Drake block (which freezes what robots have done and the leg they are driving whenever a
   batch arrives, and hands the rest to the allocator), ``register_block`` makes it a kind of
   the ``allocator`` slot, ``replace_block`` picks it in a copy of the scenario. Both runs
   then drive the same task stream and ``format_comparison`` prints their results. They set
   ``earliest_drop_offs: false``: on by default, it would improve either allocator's answers
   by local search (docs/allocation.md), and here the allocators' own answers are compared.

The task stream is generated for the seed (``tasks.generate``: two batches of four tasks,
mostly picked up in the lobby, deadlines 1.5-2.5x the estimated drive). People are left out:
this tutorial is about allocation. A Drake ``LeafSystem`` with the ``TaskAllocator``'s ports
(inputs ``progress_<robot>``, output ``plan``) registered the same way would replace the whole
block instead.

Run (``--meshcat`` shows both runs live, one after the other)::

    python tutorials/02_custom_allocator.py [--duration 120] [--meshcat] [--out DIR]
"""

import pathlib

from tutorial_common import options, run_each

from mrta_drake import load_scenario, register_block
from mrta_drake.allocation import (
    Action,
    Allocation,
    AllocationProblem,
    RobotStart,
    SmtAllocator,
    verify_allocation,
)
from mrta_drake.allocation.problem import solve_appending, stream_tasks
from mrta_drake.payloads import DROPOFF, PICKUP
from mrta_drake.results.report import format_comparison, text_table
from mrta_drake.stack.blocks import BuildContext, NoParams, replace_block, task_allocator_block

SCENARIO = pathlib.Path(__file__).resolve().parent.parent / "scenarios/hospital_6_robots.yaml"
TASKS = {
    "tasks.file": "",  # instead of the paper's five tasks, a generated stream:
    "tasks.generate": {
        "times": [0.0, 30.0], "batch_size": [4, 4], "slack": [1.5, 2.5],
        "pickup_weights": {"lobby": 4, "room_1": 1, "room_2": 1, "south_hall": 1,
                           "room_4": 1, "room_5": 1}},
    "humans.walkers": [], "humans.groups": [],
}


class EarliestPickupAllocator:
    """Tasks in order of release, then deadline, then id; each one's pickup and drop-off are
    appended to the route of the robot that completes the pickup soonest. Items already on
    board are dropped off first; each robot's previous plan is kept as it is."""

    def __init__(self, params=None):
        self.params = params

    def allocate(self, problem: AllocationProblem) -> Allocation:
        return solve_appending(problem, self._append)

    def _append(self, problem: AllocationProblem) -> Allocation:
        routes = [[Action(task, DROPOFF) for task in robot.carrying] for robot in problem.robots]
        open_tasks = [task for task in problem.tasks if problem.carrier(task.id) is None]
        for task in sorted(open_tasks, key=lambda t: (t.release, t.deadline, t.id)):
            pickup = Action(task.id, PICKUP)
            done = [problem.completion_times(r, route + [pickup])[-1]
                    for r, route in enumerate(routes)]
            best = done.index(min(done))
            routes[best] += [pickup, Action(task.id, DROPOFF)]
        return Allocation.of(problem, routes)


register_block("allocator", "earliest_pickup",
               task_allocator_block(EarliestPickupAllocator, NoParams))


def stream_problem(scenario) -> AllocationProblem:
    """The scenario's whole task stream as one problem, robots idle at their start
    locations at time 0, travel times as the allocator block sees them."""
    context = BuildContext.for_scenario(scenario)
    tasks = [task for batch in stream_tasks(scenario.tasks.stream) for task in batch]
    fleet = [RobotStart(robot.name, location, capacity=robot.capacity)
             for robot, location in zip(scenario.robots, context.start_locations, strict=True)]
    return AllocationProblem(context.travel_times, fleet, tasks, scenario.tasks.service_time,
                             scenario.source)


def main(argv=None) -> dict:
    args = options(__doc__, duration=120.0).parse_args(argv)
    scenario = load_scenario(SCENARIO, overrides=TASKS)
    problem = stream_problem(scenario)
    print(text_table(["task", "pickup", "drop-off", "release s", "deadline s"], [
        [t.id, t.pickup, t.dropoff, f"{t.release:g}", f"{t.deadline:g}"]
        for t in problem.tasks]))
    allocators = {"smt": SmtAllocator(), "earliest_pickup": EarliestPickupAllocator()}
    offline = {name: allocator.allocate(problem) for name, allocator in allocators.items()}
    violations = {name: verify_allocation(problem, allocation)
                  for name, allocation in offline.items()}
    print("\nOffline, the whole stream at once: tasks per robot in route order")
    print(text_table(["robot", *allocators], [
        [robot.name, *(" ".join(dict.fromkeys(f"t{a.task}" for a in allocation.routes[r]))
                       or "-" for allocation in offline.values())]
        for r, robot in enumerate(problem.robots)]))
    print(text_table(["", *allocators], [
        ["status", *(a.status for a in offline.values())],
        ["late tasks", *(" ".join(f"t{t}" for t in a.late_tasks) or "none"
                         for a in offline.values())],
        ["total tardiness s", *(f"{a.total_tardiness(problem):.0f}" for a in offline.values())],
        ["makespan s", *(f"{a.makespan():.0f}" for a in offline.values())],
        ["verify_allocation", *("ok" if not v else "; ".join(v) for v in violations.values())],
    ]))

    runs = run_each({name: replace_block(scenario, "allocator", name, earliest_drop_offs=False)
                     for name in allocators}, args)
    summaries = {name: run.summary for name, run in runs.items()}
    print(format_comparison(*summaries.values(), names=tuple(summaries)))
    return {"problem": problem, "offline": offline, "violations": violations,
            "summaries": summaries}


if __name__ == "__main__":
    main()
