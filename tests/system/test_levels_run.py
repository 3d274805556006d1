"""End to end across levels: four robots in the two-floor clinic carry items between its
floors through the lifts, without contacts, the same on a rerun."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mrta_drake import load_scenario, simulate
from mrta_drake.scenario.schema import HumansConfig, TaskBatch, TaskConfig, TasksConfig

from .run_fingerprint import _without_wall_clock

SCENARIO = Path(__file__).parents[2] / "scenarios" / "two_floor_6_robots.yaml"
# (pickup, drop-off) by location name: every task changes floors.
TASKS = [("L1/pharmacy", "L2/ward_b"), ("L2/icu", "L1/stores"),
         ("L1/laboratory", "L2/theatre"), ("L2/ward_a", "L1/reception")]


def _scenario():
    scenario = load_scenario(SCENARIO)
    ids = {location.name: location.id for location in scenario.locations}
    robots = [r for r in scenario.robots if r.name in ("robot1", "robot2", "robot4", "robot5")]
    stream = [TaskBatch(0.0, [TaskConfig(ids[a], ids[b], 400.0) for a, b in TASKS])]
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


def test_physics_robots_refuse_a_building_run_across_levels_in_one_line():
    from mrta_drake.errors import InputError
    from mrta_drake.stack.blocks import replace_block
    from mrta_drake.stack.diagram import build_diagram

    scenario = replace_block(_scenario(), "robots", "physics")
    with pytest.raises(InputError, match=r"blocks.robots.kind: 'physics' robots cannot ride "
                                         r"lifts \(no relocations input\)"):
        build_diagram(scenario)
