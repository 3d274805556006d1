"""Reading Open-RMF building files: the model, the coordinate systems, the per-level world."""

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mrta_drake.errors import InputError
from mrta_drake.tools.cli import main
from mrta_drake.world.rmf_building import load_building
from mrta_drake.world.rmf_coordinates import CoordinateSystem, level_transforms
from mrta_drake.world.rmf_world import BuildingWorldParams, level_world

DATA = Path(__file__).parents[1] / "data"
BUILDINGS = DATA / "buildings"
BROKEN = sorted((DATA / "broken_buildings").glob("*.building.yaml"))


@pytest.fixture(scope="module")
def one_level():
    return load_building(BUILDINGS / "one_level.building.yaml")


def vertex(level, name):
    return next(v for v in level.vertices if v.name == name)


def test_parameters_are_coerced_by_their_code(one_level):
    level = one_level.level("L1")
    charger = vertex(level, "charger_1")
    assert charger.params["is_charger"] is True and charger.flag("is_parking_spot")
    assert charger.params["spawn_robot_name"] == "tiny_1"
    assert vertex(level, "pantry").params["pickup_dispenser"] == "coke_dispenser"
    reception = vertex(level, "reception")
    assert "is_parking_spot" in reception.params and not reception.flag("is_parking_spot")
    assert all(lane.graph == 0 and lane.bidirectional for lane in level.lanes)
    assert isinstance(level.lanes[0].params["speed_limit"], float)  # [3, 0]: an int in YAML
    assert [h.width for h in level.human_lanes] == [1.5]
    assert [d.name for d in level.doors] == ["pantry_door", "lab_door"]
    assert level.floors[0].params["indoor"] == 0


def test_measured_distances_come_out_right(one_level):
    level = one_level.level("L1")
    assert len(level.measurements) == 2
    for measurement in level.measurements:
        length = math.dist(level.point(measurement.start), level.point(measurement.end))
        assert length == pytest.approx(measurement.distance, rel=1e-12)
    # Pixels are flipped: the image's top-left corner is the origin, the map lies below it.
    assert vertex(level, "pantry").xy == pytest.approx((4.0, -2.0))
    assert vertex(level, "lab").xy == pytest.approx((12.0, -2.0))


def test_walls_are_split_at_doors_and_doors_are_gaps(one_level):
    plan = level_world(one_level, "L1").floor_plan
    obstacles = plan.obstacles
    level = one_level.level("L1")
    for door in level.doors:
        a, b = np.array(level.point(door.start)), np.array(level.point(door.end))
        opening = a + np.linspace(0.02, 0.98, 25)[:, None] * (b - a)
        assert obstacles.signed_distance(opening).min() > 0.0, door.name
        beside = [a - 0.1 * (b - a) / np.linalg.norm(b - a), b + 0.1 * (b - a) /
                  np.linalg.norm(b - a)]
        assert (obstacles.signed_distance(beside) < 0).all(), door.name
    # The pantry door lies on one wall, which became two pieces meeting the door's ends.
    pieces = sorted((box for box in obstacles.boxes if box.name.startswith("wall7")),
                    key=lambda box: box.center[0])
    assert len(pieces) == 2
    assert pieces[0].center[0] + 0.5 * pieces[0].size[0] == pytest.approx(3.4)
    assert pieces[1].center[0] - 0.5 * pieces[1].size[0] == pytest.approx(4.6)
    assert all(box.size[1] == pytest.approx(0.1) and box.height == pytest.approx(2.5)
               for box in obstacles.boxes if box.name.startswith("wall"))


def test_walls_close_their_corners(one_level):
    obstacles = level_world(one_level, "L1").floor_plan.obstacles
    corners = [(0.0, 0.0), (16.0, 0.0), (16.0, -8.0), (0.0, -8.0)]
    outside = [(x + 0.04 * np.sign(x - 8.0), y + 0.04 * np.sign(y + 4.0)) for x, y in corners]
    assert (obstacles.signed_distance(outside) < 0).all()


def test_models_become_furniture_unless_they_block_a_lane(one_level):
    world = level_world(one_level, "L1", params=BuildingWorldParams(model_radius=0.4))
    obstacles = world.floor_plan.obstacles
    desk = next(box for box in obstacles.boxes if box.name.startswith("desk"))
    assert desk.center == pytest.approx((14.5, -1.2)) and desk.size == (1.4, 0.7)
    (mystery,) = obstacles.cylinders  # unknown model: a cylinder of model_radius
    assert mystery.center == pytest.approx((1.5, -1.5)) and mystery.radius == 0.4
    # The dispenser is a workcell, the coke is not static, the chair stands on a lane.
    assert not any(s.name.startswith(("coke", "chair")) for s in obstacles.boxes)
    assert world.left_out == ("chair_on_lane (OpenRobotics/Chair) at [10.00, -6.10]",)


def test_bounds_are_the_floor_plus_the_margin(one_level):
    plan = level_world(one_level, "L1", params=BuildingWorldParams(bounds_margin=0.5)).floor_plan
    assert plan.bounds == pytest.approx((-0.5, 16.5, -8.5, 0.5))
    assert plan.places["pantry"] == pytest.approx((4.0, -2.0))


def test_world_params_check_themselves():
    with pytest.raises(InputError, match="model_radius: must be > 0 m, got 0"):
        BuildingWorldParams(model_radius=0.0)


def test_levels_are_aligned_by_their_fiducials():
    building = load_building(BUILDINGS / "two_levels.building.yaml")
    first, second = building.level("L1"), building.level("L2")
    assert second.elevation == 4.0
    # L2 is drawn at another scale, turned and shifted; its own measurement says 9 m for
    # what the fiducials make 12 m, and is ignored.
    for a, b in zip(first.vertices, second.vertices, strict=True):
        assert b.xy == pytest.approx(a.xy, abs=1e-9)
    for a, b in zip(first.fiducials, second.fiducials, strict=True):
        assert b.xy == pytest.approx(a.xy, abs=1e-9)
    # A model's yaw turns with its level: drawn at +90 degrees on the turned L2.
    assert second.models[0].yaw == pytest.approx(first.models[0].yaw, abs=1e-5)
    assert second.models[0].z == pytest.approx(4.0)
    lift = building.lifts["lift_a"]
    assert lift.xy == pytest.approx((10.0, -2.0))
    assert [lft.name for lft in building.lifts_through("L2")] == ["lift_a"]


def test_lift_shafts_are_walled_but_open_at_their_doors():
    building = load_building(BUILDINGS / "two_levels.building.yaml")
    for level in ("L1", "L2"):
        obstacles = level_world(building, level).floor_plan.obstacles
        # The door faces -x: free at the door, walled on the other three faces.
        assert obstacles.signed_distance([(8.9, -2.0)])[0] > 0.3
        assert (obstacles.signed_distance([(11.1, -2.0), (10.0, -0.9), (10.0, -3.1),
                                           (8.9, -1.0)]) < 0).all()


@settings(max_examples=40, deadline=None)
@given(scale=st.floats(0.2, 5.0), turn=st.floats(-math.pi, math.pi),
       shift=st.tuples(st.floats(-500, 500), st.floats(-500, 500)))
@example(scale=3.0, turn=-math.pi, shift=(0.0, 0.0))  # a half turn: rotation pi or -pi
def test_fiducial_alignment_undoes_any_similarity(scale, turn, shift):
    """A level drawn as the reference level scaled, turned and shifted maps back onto it."""
    world = [(1.0, -1.0), (30.0, -2.0), (12.0, -25.0), (40.0, -40.0)]
    reference_pixels = [(20 * x, -20 * y) for x, y in world]  # 0.05 m per pixel

    def drawn(u, v):  # flipped pixels of the reference, turned, scaled and shifted
        x, y = u, -v
        c, s = math.cos(turn), math.sin(turn)
        return (scale * (c * x - s * y) + shift[0], -(scale * (s * x + c * y) + shift[1]))

    other_pixels = [drawn(*p) for p in reference_pixels]

    def level(name, pixels, measured):
        return SimpleNamespace(
            name=name, point=lambda i, pixels=pixels: pixels[i],
            measurements=[SimpleNamespace(start=0, end=1, distance=math.dist(*world[:2]))]
            if measured else [],
            fiducials=[SimpleNamespace(name=f"f{k}", xy=p) for k, p in enumerate(pixels)])

    levels = {"A": level("A", reference_pixels, True), "B": level("B", other_pixels, False)}
    transforms = level_transforms(CoordinateSystem("reference_image"), levels, "A", "file")
    for pixel, expected in zip(other_pixels, world, strict=True):
        assert transforms["B"].point(pixel) == pytest.approx(expected, abs=1e-6)
    # the same turn whatever its branch: -pi and pi are one rotation
    assert math.remainder(transforms["B"].rotation + turn, 2 * math.pi) == pytest.approx(
        0.0, abs=1e-9)


def test_cartesian_metres_are_used_as_they_are():
    building = load_building(BUILDINGS / "cartesian.building.yaml")
    level = building.level("ground")
    assert vertex(level, "east_shelf").xy == (8.0, 1.2)
    assert building.coordinate_system.kind == "cartesian_meters"


def test_wgs84_is_projected_to_local_metres():
    pyproj = pytest.importorskip("pyproj")
    building = load_building(BUILDINGS / "wgs84.building.yaml")
    level = building.level("L1")
    assert building.coordinate_system.crs == "EPSG:3414"
    geod = pyproj.Geod(ellps="WGS84")
    lonlat = {"gate": (103.7800, 1.3000), "hall": (103.7810, 1.3000), "lab": (103.7805, 1.3008)}
    for a, b in (("gate", "hall"), ("gate", "lab"), ("hall", "lab")):
        _, _, metres = geod.inv(*lonlat[a], *lonlat[b])
        assert math.dist(vertex(level, a).xy, vertex(level, b).xy) == pytest.approx(
            metres, rel=2e-3)
    # East is +x, north is +y, near the origin once the suggested offset is taken off.
    gate, hall, lab = (vertex(level, n).xy for n in ("gate", "hall", "lab"))
    assert hall[0] > gate[0] and lab[1] > gate[1]
    assert all(abs(c) < 1000 for c in gate)


def test_wgs84_without_pyproj_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyproj", None)
    path = BUILDINGS / "wgs84.building.yaml"
    with pytest.raises(InputError) as info:
        load_building(path)
    assert str(info.value) == (f"{path}: coordinate_system: wgs84 maps need pyproj: "
                               "pip install 'mrta-drake[rmf_wgs84]'")


@pytest.mark.parametrize("path", BROKEN, ids=[p.name.split(".")[0] for p in BROKEN])
def test_broken_building_gives_one_clear_line(path, capsys):
    """Each broken file states its expected error in its first line: ``# error: ...``."""
    first_line = path.read_text().splitlines()[0]
    assert first_line.startswith("# error: ")
    expected = f"{path}: {first_line.removeprefix('# error: ')}"
    with pytest.raises(InputError) as info:
        load_building(path)
    assert str(info.value) == expected
    assert main(["import", str(path), "--out", str(path.parent / "never")]) == 2
    assert capsys.readouterr().err == f"error: {expected}\n"
    assert not (path.parent / "never").exists()


def test_a_wgs84_position_beyond_the_poles_is_one_line(tmp_path):
    pytest.importorskip("pyproj")
    path = tmp_path / "pole.building.yaml"
    path.write_text((BUILDINGS / "wgs84.building.yaml").read_text().replace(
        "[103.7810, 1.3000, 0, hall]", "[103.7810, 123.0, 0, hall]"))
    with pytest.raises(InputError) as info:
        load_building(path)
    assert str(info.value) == (f"{path}: levels.L1.vertices[2]: [103.781, 123.0] lies "
                               "outside the range of the wgs84 coordinates")
