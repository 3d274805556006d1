"""End to end: a robot with nothing to do standing in a single-file corridor drives out of
it, away from the robot that needs it, rather than being pushed along it
(tests/data/buildings/narrow_corridor.building.yaml; the office's robots without a task
parked on single-file segments, docs/worlds.md, "Robots without a task in single-file
segments")."""

from pathlib import Path

import numpy as np

from mrta_drake import simulate
from tests.system.fixed_routes import fixed_routes

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "narrow_corridor.building.yaml"
CORRIDOR_X = (6.0, 16.0)  # m, the 1.6 m corridor between the two rooms (lane at y = 3)


def test_a_robot_without_a_task_leaves_a_single_file_corridor_another_robot_needs(tmp_path):
    # robot1 drives from west_a to east_a through the corridor, in which robot2, with
    # nothing to do, stands 1 m in from the west end.
    scenario, names = fixed_routes(BUILDING, tmp_path, [
        {"name": "robot1", "start": [1.5, 4.8, 0.0], "route": ["east_a"]},
        {"name": "robot2", "start": [7.0, 3.0, 0.0], "route": []},
    ])
    result = simulate(scenario, duration=80.0, plots=False)

    arrivals = [(e["robot"], e["location"], e["at"]) for e in result.events
                if e["type"] == "arrival"]
    assert [(robot, location) for robot, location, _ in arrivals] == [
        ("robot1", names.index("east_a"))]
    # Driving through at once takes 31.6 s; pushing robot2 along the corridor took 60.6 s.
    assert arrivals[0][2] < 40.0
    x, y = result.robot_states[-1, 1, :2]
    assert not (CORRIDOR_X[0] < x < CORRIDOR_X[1] and abs(y - 3.0) < 0.8)  # out of it
    summary = result.summary
    assert summary["deadlocks"]["count"] == 0
    assert summary["back_offs"]["count"] == 0
    assert summary["safety"]["robot_robot_contacts"] == 0
    assert summary["safety"]["robot_wall_contacts"] == 0
    assert np.isfinite(result.robot_states).all()
