"""The fleet waypoints block (one system, a ``WaypointPolicy`` per robot) and the per-robot
kind (one ``WaypointGenerator`` system per robot) run the same policies: the same run."""

import pathlib

import numpy as np
from pydrake.systems.analysis import Simulator

from mrta_drake.scenario.loading import load_scenario
from mrta_drake.stack.blocks import replace_block
from mrta_drake.stack.diagram import build_diagram

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _run(scenario, duration: float):
    stack = build_diagram(scenario)
    simulator = Simulator(stack.diagram)
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    progress = [stack.waypoint_output(k, "progress").Eval(
        stack.waypoints[0 if len(stack.waypoints) == 1 else k].GetMyContextFromRoot(context))
        for k in range(len(scenario.robots))]
    return stack, stack.recorder.arrays(), progress


def test_the_fleet_block_and_one_system_per_robot_run_alike():
    scenario = load_scenario(ROOT / "scenarios/hospital_6_robots.yaml")
    fleet, fleet_arrays, fleet_progress = _run(scenario, 40.0)
    single, single_arrays, single_progress = _run(
        replace_block(scenario, "waypoints", "roadway_per_robot"), 40.0)
    assert [s.get_name() for s in fleet.waypoints] == ["waypoints"]
    assert [s.get_name() for s in single.waypoints] == [
        f"waypoints_{r.name}" for r in scenario.robots]
    for a, b in zip(fleet_arrays, single_arrays, strict=True):
        assert np.array_equal(a, b)
    assert fleet_progress == single_progress
    assert any(p.visits for p in fleet_progress)  # some robot completed a stop
