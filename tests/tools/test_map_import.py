"""``mrta-sim import MAP.yaml --locations POINTS.yaml``: a ROS map of a small floor, made
here (a corridor with three rooms off it), becomes a scenario folder that loads and runs."""

import numpy as np
import pytest
import yaml
from PIL import Image

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.cli import main
from tests.navigation.free_space_worlds import carved

# A 24 m east-west corridor 3 m wide, three rooms of 4 x 4 m north of it behind 1.6 m doors.
FREE = [(-12.0, 12.0, -1.5, 1.5),
        (-10.0, -6.0, 3.0, 7.0), (-8.8, -7.2, 1.0, 3.5),
        (-2.0, 2.0, 3.0, 7.0), (-0.8, 0.8, 1.0, 3.5),
        (6.0, 10.0, 3.0, 7.0), (7.2, 8.8, 1.0, 3.5)]
POINTS = {"points": [{"name": "room_a", "point": [-8.0, 5.0], "parking": True},
                     {"name": "room_b", "point": [0.0, 5.0], "parking": True},
                     {"name": "room_c", "point": [8.0, 5.0], "parking": True}]}


@pytest.fixture
def floor(tmp_path):
    grid = carved(FREE, bounds=(-13.0, 13.0, -3.0, 8.0))
    pixels = np.where(grid.occupied[::-1], 0, 254).astype(np.uint8)  # top image row first
    Image.fromarray(pixels).save(tmp_path / "floor.pgm")
    (tmp_path / "floor.yaml").write_text(yaml.safe_dump(
        {"image": "floor.pgm", "resolution": grid.resolution,
         "origin": [grid.origin[0], grid.origin[1], 0.0], "negate": 0,
         "occupied_thresh": 0.65, "free_thresh": 0.25}))
    (tmp_path / "points.yaml").write_text(yaml.safe_dump(POINTS))
    return tmp_path


def test_a_ros_map_becomes_a_scenario_that_runs(floor, capsys):
    out = floor / "imported"
    assert main(["import", str(floor / "floor.yaml"), "--locations", str(floor / "points.yaml"),
                 "--robots", "3", "--people", "2", "--seed", "4", "--out", str(out)]) == 0
    assert "3 locations" in capsys.readouterr().out
    scenario = load_scenario(out / "scenario.yaml")
    assert scenario.world.kind == "ros_map"
    assert [loc.name for loc in scenario.locations] == ["room_a", "room_b", "room_c"]
    assert [r.start_location for r in scenario.robots] == [0, 1, 2]
    walk = np.array(scenario.humans.groups[0].points)
    assert len(walk) > 1 and (np.abs(walk[:, 1]) < 7.0).all()  # inside the floor
    result = simulate(scenario, duration=120.0, plots=False)
    safety = result.summary["safety"]
    assert safety["robot_wall_contacts"] == 0 and safety["robot_robot_contacts"] == 0
    assert result.summary["tasks"]["completed"] >= 1


def test_a_ros_map_needs_its_points(floor, capsys):
    assert main(["import", str(floor / "floor.yaml"), "--out", str(floor / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {floor / 'floor.yaml'}: a ROS map needs --locations POINTS.yaml "
                   "(an Open-RMF building file ends in .building.yaml)"]


def test_too_many_robots_for_the_places_is_one_line(floor, capsys):
    assert main(["import", str(floor / "floor.yaml"), "--locations", str(floor / "points.yaml"),
                 "--robots", "40", "--out", str(floor / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "points: room for" in err[0] and "asked for 40" in err[0]
