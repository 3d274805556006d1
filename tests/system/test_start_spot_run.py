"""End to end: a robot with nothing to do, pushed off its start spot between a corridor's
two lanes by a robot driving past, drives back to it (tests/data/buildings/
dead_end_dock.building.yaml; triple_H seed 1, docs/worlds.md, "Junction standoffs")."""

from pathlib import Path

import numpy as np

from mrta_drake import simulate
from tests.system.fixed_routes import fixed_routes

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "dead_end_dock.building.yaml"
SPOT = (4.2, 11.0)  # m, robot2's start spot: the corridor's centre line, 0.45 m from its lanes


def test_a_robot_pushed_off_its_start_spot_between_the_lanes_drives_back(tmp_path):
    # robot1 leaves the dock at the corridor's dead end, past robot2, which has nothing to do.
    scenario, names = fixed_routes(BUILDING, tmp_path, [
        {"name": "robot1", "start": [4.2, 13.5, -1.5708], "route": ["west", "east"]},
        {"name": "robot2", "start": [*SPOT, -1.5708], "route": []},
    ])
    result = simulate(scenario, duration=60.0, plots=False)

    arrivals = [(e["robot"], e["location"]) for e in result.events if e["type"] == "arrival"]
    assert arrivals == [("robot1", names.index("west")), ("robot1", names.index("east"))]
    off = np.hypot(*(result.robot_states[:, 1, :2] - SPOT).T)
    assert off.max() > 0.2  # pushed aside as robot1 passed
    assert off[-1] < 0.1  # and back (before, it stood 0.53 m down the corridor)
    summary = result.summary
    assert summary["deadlocks"]["count"] == 0
    assert summary["safety"]["robot_robot_contacts"] == 0
    assert summary["safety"]["robot_wall_contacts"] == 0
