"""End to end: a robot with nothing to do, pushed off its start spot between a corridor's
two lanes by a robot driving past, drives back to it (tests/data/buildings/
dead_end_dock.building.yaml; triple_H seed 1, docs/worlds.md, "Junction standoffs")."""

from pathlib import Path

import numpy as np
import yaml

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.building_import import ImportOptions, import_building

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "dead_end_dock.building.yaml"
SPOT = (4.2, 11.0)  # m, robot2's start spot: the corridor's centre line, 0.45 m from its lanes


def test_a_robot_pushed_off_its_start_spot_between_the_lanes_drives_back(tmp_path):
    import_building(str(BUILDING), str(tmp_path), ImportOptions(robots=2))
    raw = yaml.safe_load((tmp_path / "scenario.yaml").read_text())
    names = [loc["name"] for loc in
             yaml.safe_load((tmp_path / "navigation.yaml").read_text())["locations"]]
    # robot1 leaves the dock at the corridor's dead end, past robot2, which has nothing to do.
    raw["robots"] = [
        {"name": "robot1", "start": [4.2, 13.5, -1.5708],
         "route": [names.index("west"), names.index("east")]},
        {"name": "robot2", "start": [*SPOT, -1.5708], "route": []},
    ]
    raw.setdefault("blocks", {})["allocator"] = {"kind": "fixed"}
    raw.pop("tasks")
    (tmp_path / "push.yaml").write_text(yaml.safe_dump(raw))
    result = simulate(load_scenario(tmp_path / "push.yaml"), duration=60.0, plots=False)

    arrivals = [(e["robot"], e["location"]) for e in result.events if e["type"] == "arrival"]
    assert arrivals == [("robot1", names.index("west")), ("robot1", names.index("east"))]
    off = np.hypot(*(result.robot_states[:, 1, :2] - SPOT).T)
    assert off.max() > 0.2  # pushed aside as robot1 passed
    assert off[-1] < 0.1  # and back (before, it stood 0.53 m down the corridor)
    summary = result.summary
    assert summary["deadlocks"]["count"] == 0
    assert summary["safety"]["robot_robot_contacts"] == 0
    assert summary["safety"]["robot_wall_contacts"] == 0
