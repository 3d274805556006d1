"""Tests of the ROS map importer (mrta_drake/world/ros_map.py)."""

import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image
from scipy.ndimage import binary_dilation

from mrta_drake.errors import InputError
from mrta_drake.world.ros_map import load_ros_map, merge_cells, read_ros_map

REFERENCE_MAP = (Path(__file__).resolve().parents[3] / "shared" / "reference" / "hospital_map"
                 / "hospital_floor1.yaml")


def write_map(tmp_path, pixels, image_name="map.pgm", **meta) -> Path:
    """Writes ``pixels`` (top image row first; 2D grey, or 3D with channels) and a map YAML."""
    pixels = np.asarray(pixels, dtype=np.uint8)
    Image.fromarray(pixels).save(tmp_path / image_name)
    content = {"image": image_name, "resolution": 0.1, "origin": [-1.0, 2.0, 0.0],
               "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.25}
    content.update(meta)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(content))
    return path


# Pixel values and their probability p = (255 - v) / 255: 0 -> 1.0, 100 -> 0.61 (unknown in
# trinary), 205 -> 0.20 (free), 254 -> 0.004, 255 -> 0.
ROW = [0, 100, 205, 254, 255]


def test_trinary_semantics(tmp_path):
    path = write_map(tmp_path, [ROW])
    grid = read_ros_map(path)
    assert grid.occupied.tolist() == [[True, False, False, False, False]]
    grid = read_ros_map(path, unknown_is_occupied=True)
    assert grid.occupied.tolist() == [[True, True, False, False, False]]


def test_thresholds(tmp_path):
    path = write_map(tmp_path, [ROW], occupied_thresh=0.5, free_thresh=0.1)
    assert read_ros_map(path).occupied.tolist() == [[True, True, False, False, False]]
    # 205 (p = 0.196) is now unknown.
    assert read_ros_map(path, unknown_is_occupied=True).occupied.tolist() == [
        [True, True, True, False, False]]


def test_negate(tmp_path):
    path = write_map(tmp_path, [ROW], negate=1)
    # p = v / 255: 255 and 254 are occupied, 100 is unknown, 0 is free.
    assert read_ros_map(path).occupied.tolist() == [[False, False, True, True, True]]
    assert read_ros_map(path, unknown_is_occupied=True).occupied.tolist() == [
        [False, True, True, True, True]]


def test_scale_mode_uses_alpha_for_unknown(tmp_path):
    grey = np.array([[0, 100, 150, 255]], dtype=np.uint8)
    alpha = np.array([[255, 255, 0, 255]], dtype=np.uint8)
    path = write_map(tmp_path, np.dstack([grey, alpha]), image_name="map.png", mode="scale")
    # 100 lies between the thresholds: partly occupied, which counts as free.
    assert read_ros_map(path).occupied.tolist() == [[True, False, False, False]]
    assert read_ros_map(path, unknown_is_occupied=True).occupied.tolist() == [
        [True, False, True, False]]


def test_raw_mode(tmp_path):
    path = write_map(tmp_path, [[0, 50, 65, 66, 100, 101, 255]], mode="raw")
    assert read_ros_map(path).occupied.tolist() == [
        [False, False, False, True, True, False, False]]
    assert read_ros_map(path, unknown_is_occupied=True).occupied.tolist() == [
        [False, False, False, True, True, True, True]]


def test_colour_image_uses_mean_of_channels(tmp_path):
    rgb = np.array([[[0, 0, 0], [255, 0, 0], [255, 255, 255]]], dtype=np.uint8)
    path = write_map(tmp_path, rgb, image_name="map.png")
    # Mean 85 gives p = 0.67 > 0.65: occupied.
    assert read_ros_map(path).occupied.tolist() == [[True, True, False]]


def test_rows_are_flipped_and_placed(tmp_path):
    pixels = np.full((2, 3), 255, dtype=np.uint8)
    pixels[0, 0] = 0  # top-left pixel: the map's north-west cell
    path = write_map(tmp_path, pixels)
    grid = read_ros_map(path)
    assert grid.shape == (2, 3)
    assert grid.occupied[1, 0] and grid.occupied.sum() == 1
    assert grid.origin == (-1.0, 2.0)
    assert grid.resolution == 0.1
    np.testing.assert_allclose(grid.extent, (-1.0, -0.7, 2.0, 2.2))
    assert not grid.is_free([[-0.95, 2.15]])[0]
    assert grid.is_free([[-0.95, 2.05]])[0]


def test_floor_plan_boxes_cover_exactly_the_occupied_cells(tmp_path):
    rng = np.random.default_rng(7)
    pixels = np.where(rng.random((40, 60)) < 0.3, 0, 255).astype(np.uint8)
    pixels[5:15, 10:12] = 0
    plan = load_ros_map(write_map(tmp_path, pixels), simplify=0.0)
    assert plan.name == "map"
    assert plan.places == {}
    np.testing.assert_allclose(plan.bounds, (-1.0, 5.0, 2.0, 6.0))
    np.testing.assert_array_equal(plan.raw_grid.occupied, pixels[::-1] == 0)
    np.testing.assert_array_equal(plan.occupancy(0.1).occupied, plan.raw_grid.occupied)
    assert len(plan.obstacles) < plan.raw_grid.occupied.sum()


@pytest.mark.parametrize("block", [1, 2, 3, 5])
def test_merge_cells(block):
    rng = np.random.default_rng(block)
    occupied = rng.random((37, 53)) < 0.25
    occupied[3:20, 4:9] = True
    rects = merge_cells(occupied, block)
    covered = np.zeros(occupied.shape, dtype=int)
    for r0, r1, c0, c1 in rects:
        assert 0 <= r0 < r1 <= occupied.shape[0] and 0 <= c0 < c1 <= occupied.shape[1]
        covered[r0:r1, c0:c1] += 1
    assert (covered[occupied] > 0).all()
    if block == 1:
        np.testing.assert_array_equal(covered, occupied.astype(int))  # exact, no overlaps
    else:
        # Extra cells lie within block - 1 cells (in x and y) of an occupied cell.
        near = binary_dilation(occupied, np.ones((2 * block - 1, 2 * block - 1), dtype=bool))
        assert (near[covered > 0]).all()
        assert len(rects) < len(merge_cells(occupied, 1))


def test_merge_cells_empty():
    assert merge_cells(np.zeros((4, 5), dtype=bool)).shape == (0, 4)


@pytest.mark.parametrize("change, field, message", [
    ({"resolution": -0.05}, "resolution", "must be > 0, got -0.05"),
    ({"origin": [0.0, 0.0, 0.5]}, "origin", "yaw 0.5 is not supported (rotated maps), use 0"),
    ({"origin": [0.0]}, "origin", "expected [x, y] or [x, y, yaw], got [0.0]"),
    ({"mode": "fancy"}, "mode", "expected one of trinary, scale, raw, got 'fancy'"),
    ({"negate": 2}, "negate", "expected 0 or 1, got 2"),
    ({"free_thresh": 0.7}, "free_thresh",
     "need 0 <= free_thresh < occupied_thresh <= 1, got 0.7 and 0.65"),
    ({"colour": "red"}, "colour", "unknown field (known: free_thresh, image, mode, negate, "
     "occupied_thresh, origin, resolution)"),
])
def test_bad_map_yaml(tmp_path, change, field, message):
    path = write_map(tmp_path, [ROW], **change)
    with pytest.raises(InputError) as info:
        read_ros_map(path)
    assert str(info.value) == f"{path}: {field}: {message}"


def test_missing_and_unreadable_image(tmp_path):
    path = write_map(tmp_path, [ROW], image="other.pgm")
    with pytest.raises(InputError) as info:
        read_ros_map(path)
    assert str(info.value) == f"{path}: image: file not found: {tmp_path / 'other.pgm'}"
    (tmp_path / "broken.pgm").write_bytes(b"P5 not really an image")
    path = write_map(tmp_path, [ROW], image="broken.pgm")
    with pytest.raises(InputError) as info:
        read_ros_map(path)
    message = str(info.value)
    assert message.startswith(f"{path}: image: {tmp_path / 'broken.pgm'}: cannot read the image")
    assert "\n" not in message


def test_missing_yaml(tmp_path):
    with pytest.raises(InputError) as info:
        load_ros_map(tmp_path / "none.yaml")
    assert str(info.value) == f"{tmp_path / 'none.yaml'}: ROS map file not found"


@pytest.fixture(scope="module")
def reference_map():
    if not REFERENCE_MAP.is_file():
        pytest.skip("reference map not available")
    return REFERENCE_MAP


def test_reference_map_exact_import(reference_map):
    start = time.perf_counter()
    plan = load_ros_map(reference_map, simplify=0.0)
    elapsed = time.perf_counter() - start
    grid = plan.raw_grid
    assert grid.shape == (1119, 500)
    np.testing.assert_allclose(plan.bounds, (-12.5, 12.5, -35.0, 20.95))
    # Only black is occupied. The map's grey (205, p = 0.196) is below free_thresh 0.25, so it
    # is free under ROS semantics, whatever is done with unknown cells.
    assert grid.occupied.sum() == 27625
    assert read_ros_map(reference_map, unknown_is_occupied=True).occupied.sum() == 27625
    np.testing.assert_array_equal(plan.occupancy(0.05).occupied, grid.occupied)
    assert len(plan.obstacles) <= 5000
    assert elapsed < 1.0


def test_reference_map_default_import_is_simplified(reference_map):
    start = time.perf_counter()
    plan = load_ros_map(reference_map)
    assert time.perf_counter() - start < 1.0
    assert len(plan.obstacles) <= 800
    occupied = plan.occupancy(0.05).occupied
    raw = plan.raw_grid.occupied
    assert occupied[raw].all()
    assert binary_dilation(raw, np.ones((7, 7), dtype=bool))[occupied].all()  # within 0.15 m


def test_sixteen_bit_image_is_rejected(tmp_path):
    Image.fromarray(np.zeros((2, 2), dtype=np.uint16)).save(tmp_path / "deep.png")
    path = write_map(tmp_path, [ROW], image="deep.png")
    with pytest.raises(InputError) as info:
        read_ros_map(path)
    assert str(info.value).startswith(f"{path}: image: {tmp_path / 'deep.png'}: unsupported pixel "
                                      "format I")
