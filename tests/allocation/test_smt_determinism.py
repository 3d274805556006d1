"""The SMT allocator's answers depend only on the problem: the hospital with people and a busy
task stream, simulated twice in one process, gives bit-identical robot states and events
(less the wall-clock ``solve_time``), with the greedy start, without it, and with a budget so
small that z3 runs out of it."""

import json
import pathlib

import numpy as np
import pytest

from mrta_drake import load_scenario, simulate
from tests.system.run_fingerprint import _without_wall_clock

HOSPITAL = pathlib.Path(__file__).resolve().parents[2] / "scenarios/hospital_6_robots.yaml"
DURATION = 90.0  # s: 6 allocations
BUSY_STREAM = {"rate": 0.1, "batch_size": [1, 3], "slack": [1.2, 3.0]}
TINY_BUDGET = 1500  # z3 resource units: runs out in the allocations with a real search


def allocations(result) -> list[dict]:
    return [event["event"] for event in result.events if event["type"] == "allocation"]


def searched(event: dict, params: dict) -> bool:
    """Whether z3 searched in this allocation: without the greedy start it searches for
    every batch with tasks; with it, an infeasible answer is z3's proof."""
    if params.get("greedy_start", True):
        return event["status"] == "infeasible"
    return any(tasks for _, tasks in event["assignment"])


@pytest.mark.parametrize("params", [
    {},
    {"greedy_start": False},
    {"greedy_start": False, "budget": TINY_BUDGET},
], ids=["greedy_start", "search_only", "tiny_budget"])
def test_two_runs_in_one_process_are_bit_identical(params):
    scenario = load_scenario(HOSPITAL, overrides={"tasks.generate": BUSY_STREAM,
                                                  "blocks.allocator.params": params})
    assert scenario.humans.walkers
    first, second = (simulate(scenario, duration=DURATION, plots=False) for _ in range(2))
    events = allocations(first)
    assert sum(searched(event, params) for event in events) >= 5
    if "budget" in params:
        assert sum("budget ran out" in event["note"] for event in events) >= 3
    assert np.array_equal(first.times, second.times)
    assert np.array_equal(first.robot_states, second.robot_states)
    assert np.array_equal(first.human_positions, second.human_positions)
    assert (json.dumps(_without_wall_clock(first.events), default=repr)
            == json.dumps(_without_wall_clock(second.events), default=repr))
