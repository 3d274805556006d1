"""End to end: six robots sent through a crossing of two-lane corridors from all four arms
at once drive through its loop one at a time (tests/data/buildings/
crossroads.building.yaml; docs/worlds.md, "Junction reservations")."""

from pathlib import Path

import numpy as np
import yaml

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.building_import import ImportOptions, import_building

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "crossroads.building.yaml"
CROSSING = (8.0, 8.0)  # m, where the corridors' centre lines cross
LOOP = 0.9  # m: the loop's corners lie 0.64 m from the crossing, its links 0.45 m


def test_robots_from_every_arm_take_the_crossing_one_at_a_time(tmp_path):
    import_building(str(BUILDING), str(tmp_path), ImportOptions(robots=4))
    raw = yaml.safe_load((tmp_path / "scenario.yaml").read_text())
    navigation = yaml.safe_load((tmp_path / "navigation.yaml").read_text())
    assert len(navigation["roadways"]["junctions"]) == 1
    names = [loc["name"] for loc in navigation["locations"]]
    # On each arm's lane towards the crossing, 2-4.5 m from it; every robot turns or
    # crosses (before junctions were reserved, two robots stood in the loop together).
    starts = {"south": lambda d: [8.45, 8 - d, 1.5708], "north": lambda d: [7.55, 8 + d, -1.5708],
              "west": lambda d: [8 - d, 7.55, 0.0], "east": lambda d: [8 + d, 8.45, 3.1416]}
    plan = [("south", 4.5, "west"), ("south", 3.3, "east"), ("north", 3.0, "east"),
            ("north", 4.2, "west"), ("west", 2.0, "north"), ("east", 2.0, "south")]
    raw["robots"] = [{"name": f"robot{k + 1}", "start": starts[arm](distance),
                      "route": [names.index(to)]}
                     for k, (arm, distance, to) in enumerate(plan)]
    raw.setdefault("blocks", {})["allocator"] = {"kind": "fixed"}
    raw.pop("tasks")
    (tmp_path / "crossing.yaml").write_text(yaml.safe_dump(raw))
    result = simulate(load_scenario(tmp_path / "crossing.yaml"), duration=90.0, plots=False)

    arrivals = sorted((e["robot"], e["location"]) for e in result.events
                      if e["type"] == "arrival")
    assert arrivals == sorted((f"robot{k + 1}", names.index(to))
                              for k, (_, _, to) in enumerate(plan))
    near = np.hypot(*(result.robot_states[:, :, :2] - CROSSING).transpose(2, 0, 1)) < LOOP
    assert near.any(axis=0).all()  # every robot drove through
    assert near.sum(axis=1).max() == 1  # one at a time
    summary = result.summary
    assert summary["deadlocks"]["count"] == 0
    assert summary["safety"]["robot_robot_contacts"] == 0
    assert summary["safety"]["robot_wall_contacts"] == 0
