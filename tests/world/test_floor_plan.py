"""Tests of the floor-plan format and its loader (mrta_drake/world/floor_plan.py)."""

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from mrta_drake.errors import InputError
from mrta_drake.world.floor_plan import arc_boxes, load_floor_plan
from mrta_drake.world.obstacles import Obstacles

BROKEN = sorted((Path(__file__).parents[1] / "data" / "broken_floor_plans").glob("*.yaml"))


def write_plan(tmp_path, plan: dict) -> Path:
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan))
    return path


def boxes_by_name(plan):
    return {box.name: box for box in plan.obstacles.boxes}


def test_round_trip(tmp_path):
    path = write_plan(tmp_path, {
        "name": "ward",
        "bounds": [-1.0, 9.0, -2.0, 6.0],
        "wall_height": 2.0,
        "wall_thickness": 0.2,
        "walls": [
            {"name": "south", "from": [0.0, 0.0], "to": [4.0, 0.0],
             "doors": [{"center": [2.0, 0.05], "width": 1.0}]},
            {"from": [4.0, 0.0], "to": [4.0, 3.0], "thickness": 0.1},
        ],
        "furniture": [
            {"name": "bed", "box": {"center": [1.0, 2.0], "size": [2.0, 0.9], "yaw": 0.5,
                                    "height": 0.6}},
            {"name": "planter", "cylinder": {"center": [3.0, 2.0], "radius": 0.3}},
            {"name": "desk", "arc": {"center": [6.0, 2.0], "radius": 1.5, "thickness": 0.3,
                                     "start": 0.0, "end": math.pi, "segments": 4}},
        ],
        "places": {"door": [2.0, -1.0], "bed_side": [1.0, 3.0]},
    })
    plan = load_floor_plan(path)
    assert plan.name == "ward"
    assert plan.bounds == (-1.0, 9.0, -2.0, 6.0)
    assert plan.wall_height == 2.0
    assert plan.source == str(path)
    assert plan.raw_grid is None
    assert plan.places == {"door": (2.0, -1.0), "bed_side": (1.0, 3.0)}
    boxes = boxes_by_name(plan)
    assert set(boxes) == {"south_0", "south_1", "wall1", "bed",
                          "desk_0", "desk_1", "desk_2", "desk_3"}
    # The door splits the wall; outer ends get half a thickness of end cap.
    np.testing.assert_allclose(boxes["south_0"].center, (0.7, 0.0))
    np.testing.assert_allclose(boxes["south_0"].size, (1.6, 0.2))
    np.testing.assert_allclose(boxes["south_1"].center, (3.3, 0.0))
    assert boxes["south_1"].height == 2.0
    np.testing.assert_allclose(boxes["wall1"].center, (4.0, 1.5))
    np.testing.assert_allclose(boxes["wall1"].size, (3.1, 0.1))
    assert boxes["wall1"].yaw == pytest.approx(math.pi / 2)
    assert (boxes["bed"].center, boxes["bed"].size, boxes["bed"].yaw, boxes["bed"].height) == (
        (1.0, 2.0), (2.0, 0.9), 0.5, 0.6)
    (planter,) = plan.obstacles.cylinders
    assert (planter.name, planter.center, planter.radius, planter.height) == (
        "planter", (3.0, 2.0), 0.3, 1.0)


def test_occupancy_shows_walls_and_doors(tmp_path):
    path = write_plan(tmp_path, {
        "name": "room", "bounds": [0.0, 4.0, 0.0, 2.0],
        "walls": [{"from": [0.0, 1.0], "to": [4.0, 1.0],
                   "doors": [{"center": [2.0, 1.0], "width": 1.0}]}],
    })
    grid = load_floor_plan(path).occupancy(0.05)
    assert grid.shape == (40, 80)
    assert grid.origin == (0.0, 0.0)
    assert not grid.is_free([[1.0, 1.0], [3.0, 1.0]]).any()
    assert grid.is_free([[2.0, 1.0], [1.0, 0.5], [1.0, 1.5]]).all()


def test_door_at_a_wall_end_leaves_no_cap(tmp_path):
    path = write_plan(tmp_path, {
        "name": "room", "bounds": [0.0, 5.0, 0.0, 5.0], "wall_thickness": 0.2,
        "walls": [{"name": "w", "from": [0.0, 0.0], "to": [4.0, 0.0],
                   "doors": [{"center": [3.5, 0.0], "width": 1.0}]}],
    })
    (box,) = load_floor_plan(path).obstacles.boxes
    assert box.name == "w"
    np.testing.assert_allclose(box.center, (1.45, 0.0))
    np.testing.assert_allclose(box.size, (3.1, 0.2))


def test_walls_meeting_at_a_corner_close_it(tmp_path):
    path = write_plan(tmp_path, {
        "name": "corner", "bounds": [-1.0, 3.0, -1.0, 3.0], "wall_thickness": 0.2,
        "walls": [{"from": [0.0, 0.0], "to": [2.0, 0.0]}, {"from": [0.0, 0.0], "to": [0.0, 2.0]}],
    })
    obstacles = load_floor_plan(path).obstacles
    assert obstacles.signed_distance([[-0.09, -0.09]])[0] < 0.0


def test_arc_boxes_form_a_closed_band():
    boxes = arc_boxes("desk", (0.0, 0.0), 3.0, 0.4, 0.0, math.pi, 8, 1.0)
    assert [b.name for b in boxes] == [f"desk_{k}" for k in range(8)]
    obstacles = Obstacles(tuple(boxes))
    angles = np.linspace(0.0, math.pi, 181)
    for radius in (2.87, 3.0, 3.19):
        points = radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        assert (obstacles.signed_distance(points) < 0.0).all(), radius
    outside = np.array([[0.0, 3.3], [0.0, 2.7], [0.0, -0.3]])
    assert (obstacles.signed_distance(outside) > 0.0).all()


def test_defaults(tmp_path):
    path = write_plan(tmp_path, {
        "name": "bare", "bounds": [0.0, 1.0, 0.0, 1.0],
        "walls": [{"from": [0.0, 0.5], "to": [1.0, 0.5]}],
        "furniture": [{"name": "desk", "arc": {"center": [0.5, 0.5], "radius": 0.3,
                                               "thickness": 0.1, "start": 0.0, "end": 1.0}},
                      {"name": "box", "box": {"center": [0.5, 0.5], "size": [0.1, 0.1]}}],
    })
    plan = load_floor_plan(path)
    assert plan.wall_height == 2.5
    assert plan.places == {}
    boxes = boxes_by_name(plan)
    assert boxes["wall0"].size[1] == pytest.approx(0.15)
    assert boxes["wall0"].height == 2.5
    assert len([b for b in boxes if b.startswith("desk_")]) == 8
    assert (boxes["box"].yaw, boxes["box"].height) == (0.0, 1.0)


def test_missing_file(tmp_path):
    path = tmp_path / "nowhere.yaml"
    with pytest.raises(InputError) as info:
        load_floor_plan(path)
    assert str(info.value) == f"{path}: floor-plan file not found"


@pytest.mark.parametrize("path", BROKEN, ids=[p.stem for p in BROKEN])
def test_broken_file_gives_one_clear_line(path):
    """Each broken file states its expected error in its first line: ``# error: ...``."""
    first_line = path.read_text().splitlines()[0]
    assert first_line.startswith("# error: ")
    with pytest.raises(InputError) as info:
        load_floor_plan(path)
    message = str(info.value)
    assert "\n" not in message
    assert message == f"{path}: {first_line.removeprefix('# error: ')}"
    assert info.value.file == str(path)
