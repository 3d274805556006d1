"""The six-robot hospital over a lossy network with latency (docs/fidelity.md)."""

import pathlib

from pydrake.systems.framework import DiagramBuilder

from mrta_drake import load_scenario, simulate
from mrta_drake.stack.diagram import add_stack

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios/hospital_6_robots.yaml"
LOSSY = {"communication.latency": 0.2, "communication.loss": 0.1}


def test_over_a_lossy_network_with_latency_every_task_is_done_without_contacts():
    summary = simulate(load_scenario(SCENARIO, overrides=LOSSY), duration=300.0,
                       plots=False).summary
    tasks, safety = summary["tasks"], summary["safety"]
    assert tasks["completed"] == tasks["total"] == 5
    assert safety["robot_robot_contacts"] == safety["robot_wall_contacts"] == 0
    assert safety["robot_human_contacts"] == 0
    ages = summary["communication"]["age_of_information"]
    assert 0.2 <= ages["mean"] <= ages["p95"] <= ages["max"]


def test_only_a_network_that_is_not_ideal_is_added():
    def systems(overrides):
        builder = DiagramBuilder()
        add_stack(builder, load_scenario(SCENARIO, overrides=overrides))
        return {system.get_name() for system in builder.GetSystems()}

    assert "network" not in systems({})
    assert "network" in systems(LOSSY)
