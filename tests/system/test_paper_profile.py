"""``profile: paper`` loads and runs every shipped scenario."""

import pathlib

import numpy as np
import pytest

from mrta_drake import load_scenario, simulate
from mrta_drake.scenario.validate import validate_scenario

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "scenarios").glob("*.yaml"))


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_paper_profile_runs_every_shipped_scenario(path):
    validate_scenario(path, overrides={"profile": "paper"})
    scenario = load_scenario(path, overrides={"profile": "paper"})
    assert scenario.profile == "paper"
    assert scenario.blocks.planner.params == {"cost_resting_robots": False}
    # Robots without a task stay on their points in the paper (no parking): run until 15 s
    # after the first batch arrives.
    first_batch = min((batch.arrival for batch in scenario.tasks.stream), default=0.0)
    result = simulate(scenario, duration=first_batch + 15.0, plots=False)
    moved = np.linalg.norm(result.robot_states[-1, :, :2] - result.robot_states[0, :, :2],
                           axis=1)
    assert moved.max() > 0.5
    assert result.summary["controller_failures"] == 0
