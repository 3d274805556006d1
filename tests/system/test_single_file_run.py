"""End to end: two robots sent through one single-file corridor from both ends at once
take turns (tests/data/buildings/narrow_corridor.building.yaml)."""

from pathlib import Path

import numpy as np

from mrta_drake import simulate
from tests.system.fixed_routes import fixed_routes

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "narrow_corridor.building.yaml"
CORRIDOR_X = (6.0, 16.0)  # m, the 1.6 m corridor between the two rooms


def test_robots_from_both_ends_take_turns_in_a_single_file_corridor(tmp_path):
    # From the docks at the same time: robot1 east and back west, robot2 west and back east.
    scenario, names = fixed_routes(BUILDING, tmp_path, [
        {"name": "robot1", "start": [4.5, 4.8, -2.27], "route": ["east_b", "west_a"]},
        {"name": "robot2", "start": [17.5, 1.2, 0.88], "route": ["west_b", "east_a"]},
    ])
    west_a, west_b, east_a, east_b = (names.index(n) for n in
                                      ("west_a", "west_b", "east_a", "east_b"))
    result = simulate(scenario, duration=150.0, plots=False)

    arrivals = [e for e in result.events if e["type"] == "arrival"]
    assert sorted((e["robot"], e["location"]) for e in arrivals) == sorted(
        [("robot1", east_b), ("robot1", west_a), ("robot2", west_b), ("robot2", east_a)])
    x, heading = result.robot_states[:, :, 0], result.robot_states[:, :, 2]
    inside = (x > CORRIDOR_X[0]) & (x < CORRIDOR_X[1])
    assert inside[:, 0].any() and inside[:, 1].any()
    both = inside[:, 0] & inside[:, 1]  # one may follow the other, never meet it head-on
    east = np.cos(heading) > 0.0
    assert (east[both, 0] == east[both, 1]).all(), "robots met head-on in the corridor"
    summary = result.summary
    assert summary["deadlocks"]["count"] == 0
    assert summary["safety"]["robot_wall_contacts"] == 0
    assert summary["safety"]["robot_robot_contacts"] == 0
    assert np.isfinite(result.robot_states).all()
