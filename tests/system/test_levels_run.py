"""End to end across levels: robots in the two-floor clinic carry items between its floors
through the lifts, without contacts, the same on a rerun, on either robots backend."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.framework import LeafSystem

from mrta_drake import load_scenario, simulate
from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import HumansConfig, TaskBatch, TaskConfig, TasksConfig
from mrta_drake.stack.blocks import BlockType, NoParams, register_block, replace_block
from mrta_drake.stack.diagram import build_diagram

from .run_fingerprint import _without_wall_clock

SCENARIO = Path(__file__).parents[2] / "scenarios" / "two_floor_6_robots.yaml"
# (pickup, drop-off) by location name: every task changes floors.
TASKS = [("L1/pharmacy", "L2/ward_b"), ("L2/icu", "L1/stores"),
         ("L1/laboratory", "L2/theatre"), ("L2/ward_a", "L1/reception")]


def _scenario(names=("robot1", "robot2", "robot4", "robot5"), tasks=TASKS):
    """The two-floor clinic with robots ``names`` only, no people, and ``tasks`` at 0 s."""
    scenario = load_scenario(SCENARIO)
    ids = {location.name: location.id for location in scenario.locations}
    robots = [r for r in scenario.robots if r.name in names]
    stream = [TaskBatch(0.0, [TaskConfig(ids[a], ids[b], 400.0) for a, b in tasks])]
    return dataclasses.replace(scenario, robots=robots, humans=HumansConfig(),
                               tasks=dataclasses.replace(TasksConfig(), stream=stream))


def test_tasks_across_floors_complete_through_the_lifts_and_rerun_identically():
    scenario = _scenario()
    first = simulate(scenario, duration=240.0, plots=False)
    summary = first.summary
    assert summary["tasks"]["completed"] == len(TASKS)
    riders = {e["robot"] for e in first.events if e["type"] == "lift" and e["kind"] == "arrive"}
    assert {task["robot"] for task in summary["tasks"]["per_task"]} <= riders
    safety = summary["safety"]
    assert safety["robot_robot_contacts"] == 0 and safety["robot_wall_contacts"] == 0
    assert summary["deadlocks"]["count"] == 0
    # Regression: a rider re-planned between its relocation and its waypoint generator's next
    # target was planned back to the berth on the level it left (2 failures here).
    assert summary["planner_failures"] == 0
    again = simulate(scenario, duration=240.0, plots=False)
    assert np.array_equal(first.robot_states, again.robot_states)
    assert _without_wall_clock(first.events) == _without_wall_clock(again.events)


def test_physics_robots_ride_a_lift_each_way_and_rerun_identically():
    # Two robots on the physics backend, one task each way between the floors: the plant
    # puts each rider on the other level (~3 s of CPU time a run of 100 s).
    scenario = _scenario(["robot1", "robot5"], TASKS[3:4] + TASKS[:1])
    scenario = replace_block(scenario, "robots", "physics")
    first = simulate(scenario, duration=100.0, plots=False)
    summary = first.summary
    assert summary["tasks"]["completed"] == 2
    arrivals = [e for e in first.events if e["type"] == "lift" and e["kind"] == "arrive"]
    assert sorted(e["robot"] for e in arrivals) == ["robot1", "robot5"]
    assert summary["physics_contacts"]["count"] == 0
    assert summary["deadlocks"]["count"] == 0 and summary["planner_failures"] == 0
    again = simulate(scenario, duration=100.0, plots=False)
    assert np.array_equal(first.robot_states, again.robot_states)
    assert _without_wall_clock(first.events) == _without_wall_clock(again.events)


class _FixedRobots(LeafSystem):
    """A robots block without a ``relocations`` input: robots that stand at their starts."""

    def __init__(self, starts):
        super().__init__()
        state = np.column_stack([starts, np.zeros(len(starts))]).ravel()
        self.DeclareVectorInputPort("commands", 2 * len(starts))
        self.DeclareVectorOutputPort("state", len(state),
                                     lambda context, output: output.SetFromVector(state))


def test_a_robots_block_without_relocations_is_refused_a_building_run_across_levels():
    register_block("robots", "fixed", BlockType(
        NoParams, lambda ctx, params: _FixedRobots(np.asarray(ctx.robot_starts))))
    scenario = replace_block(_scenario(), "robots", "fixed")
    with pytest.raises(InputError, match=r"blocks.robots.kind: 'fixed' robots cannot ride "
                                         r"lifts \(no relocations input\)"):
        build_diagram(scenario)
