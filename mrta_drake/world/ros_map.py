"""Importer for ROS ``map_server`` maps (a YAML file and a PGM/PNG image) as a ``FloorPlan``.

The YAML file is read into ``RosMapFile``. A pixel's value v is the mean of its colour
channels (alpha excluded); ``negate`` replaces v by 255 - v. Then:

- trinary: p = (255 - v) / 255; occupied if p > occupied_thresh, free if p < free_thresh,
  unknown otherwise.
- scale: like trinary, except that pixels with alpha < 255 are unknown and values between the
  thresholds are partly occupied, which a boolean grid counts as free.
- raw: v is the occupancy in percent; v > 100 is unknown, otherwise occupied if
  v / 100 > occupied_thresh.

Unknown cells are free unless ``unknown_is_occupied`` (the original stack drove through
unknown space). Occupied cells are merged into axis-aligned boxes. With ``simplify`` = 0 their
union is exactly the occupied cells; a scanned map's ragged walls and specks then need
thousands of boxes (4929 for the reference hospital map, which has 1030 separate occupied
patches), too many for the plant and the per-step geometric queries. By default boxes may
reach up to ``simplify`` = 0.15 m beyond occupied cells (never leaving one out), which gives
751 boxes for that map. The image's top row is the map's north edge (largest y); the world
frame is x east, y north, metres.
"""

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from mrta_drake.errors import InputError
from mrta_drake.scenario.typed_yaml import load_typed, read_yaml
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.floor_plan_format import check_number, check_numbers
from mrta_drake.world.obstacles import Box, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid

_MODES = ("trinary", "scale", "raw")


@dataclass(frozen=True)
class RosMapFile:
    """A ``map_server`` map YAML, with ROS semantics: ``image`` (path relative to the YAML
    file), ``resolution`` (m per pixel), ``origin`` ([x, y] or [x, y, yaw]: world position of
    the lower-left pixel's corner, m; yaw must be 0), ``negate`` (0 or 1), the thresholds
    (0 <= ``free_thresh`` < ``occupied_thresh`` <= 1) and ``mode`` (``trinary``, ``scale``
    or ``raw``)."""

    image: str
    resolution: float
    origin: list[float]
    negate: int = 0
    occupied_thresh: float = 0.65
    free_thresh: float = 0.25
    mode: str = "trinary"

    def __post_init__(self):
        if not self.image:
            raise InputError(None, "image", "expected a non-empty string, got ''")
        check_number(self.resolution, "resolution", positive=True)
        if len(self.origin) not in (2, 3):
            raise InputError(None, "origin", f"expected [x, y] or [x, y, yaw], got {self.origin}")
        check_number(tuple(self.origin), "origin")
        if len(self.origin) == 3 and self.origin[2] != 0.0:
            raise InputError(None, "origin", f"yaw {self.origin[2]:g} is not supported "
                             "(rotated maps), use 0")
        if self.negate not in (0, 1):
            raise InputError(None, "negate", f"expected 0 or 1, got {self.negate!r}")
        check_numbers(self, finite=("occupied_thresh", "free_thresh"))
        if not 0.0 <= self.free_thresh < self.occupied_thresh <= 1.0:
            raise InputError(None, "free_thresh", f"need 0 <= free_thresh < occupied_thresh "
                             f"<= 1, got {self.free_thresh:g} and {self.occupied_thresh:g}")
        if self.mode not in _MODES:
            raise InputError(None, "mode", f"expected one of {', '.join(_MODES)}, got "
                             f"{self.mode!r}")


def load_ros_map(yaml_path, unknown_is_occupied: bool = False, simplify: float = 0.15,
                 wall_height: float = 2.5) -> FloorPlan:
    """Imports a ROS map as a floor plan: merged boxes of ``wall_height`` m, no places, and
    the map's occupancy as ``raw_grid``. ``simplify`` (m, >= 0): how far boxes may reach
    beyond occupied cells (0: exactly the occupied cells)."""
    if simplify < 0.0:
        raise ValueError(f"simplify must be >= 0, got {simplify}")
    grid = read_ros_map(yaml_path, unknown_is_occupied)
    block = 1 + int(math.floor(simplify / grid.resolution + 1e-9))
    rects = merge_cells(grid.occupied, block)
    res = grid.resolution
    x0, y0 = grid.origin
    boxes = tuple(
        Box(name=f"map{k}",
            center=(x0 + 0.5 * (c0 + c1) * res, y0 + 0.5 * (r0 + r1) * res),
            size=((c1 - c0) * res, (r1 - r0) * res), height=wall_height)
        for k, (r0, r1, c0, c1) in enumerate(rects.tolist()))
    return FloorPlan(name=Path(yaml_path).stem, bounds=grid.extent, wall_height=wall_height,
                     obstacles=Obstacles(boxes), places={}, source=str(yaml_path), raw_grid=grid)


def read_ros_map(yaml_path, unknown_is_occupied: bool = False) -> OccupancyGrid:
    """The occupancy of a ROS map (row 0 = south edge), unknown cells counted as
    ``unknown_is_occupied``."""
    path = str(yaml_path)
    meta = load_typed(read_yaml(path, "ROS map file"), RosMapFile, path)
    image_path = Path(path).parent / meta.image
    value, alpha = _read_image(path, image_path)
    if meta.negate:
        value = 255.0 - value
    if meta.mode == "raw":
        unknown = value > 100.0
        occupied = ~unknown & (value / 100.0 > meta.occupied_thresh)
    else:
        p = (255.0 - value) / 255.0
        occupied = p > meta.occupied_thresh
        if meta.mode == "trinary":
            unknown = ~occupied & (p >= meta.free_thresh)
        else:
            unknown = alpha < 255
            occupied &= ~unknown
    if unknown_is_occupied:
        occupied |= unknown
    return OccupancyGrid(np.ascontiguousarray(occupied[::-1]), meta.resolution,
                         (meta.origin[0], meta.origin[1]))


def _read_image(yaml_path: str, image_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Grey value (mean of colour channels) and alpha (255 when absent) per pixel, float
    arrays in image row order (top row first); InputError naming the map file's ``image``
    when it cannot be read."""
    if not image_path.is_file():
        raise InputError(yaml_path, "image", f"file not found: {image_path}")
    try:
        with Image.open(image_path) as image:
            image.load()
    except (OSError, ValueError, SyntaxError) as e:  # Pillow's errors for corrupt files
        raise InputError(yaml_path, "image",
                         f"{image_path}: cannot read the image ({e})") from None
    if image.mode in ("1", "P"):
        image = image.convert("L" if image.mode == "1" else "RGBA")
    if image.mode not in ("L", "LA", "RGB", "RGBA"):
        raise InputError(yaml_path, "image",
                         f"{image_path}: unsupported pixel format {image.mode}")
    pixels = np.asarray(image, dtype=float)
    if pixels.ndim == 2:
        return pixels, np.full(pixels.shape, 255.0)
    has_alpha = pixels.shape[2] in (2, 4)
    color = pixels[..., :-1] if has_alpha else pixels
    alpha = pixels[..., -1] if has_alpha else np.full(pixels.shape[:2], 255.0)
    return color.mean(axis=2), alpha


def merge_cells(occupied: np.ndarray, block: int = 1) -> np.ndarray:
    """Axis-aligned rectangles covering the True cells of ``occupied``, as rows
    [row_begin, row_end, col_begin, col_end) of an int array (n, 4).

    With ``block`` = 1 the rectangles' union is exactly the True cells: each row's runs of
    True cells, merged with identical runs of the rows above. With ``block`` > 1 the grid is
    first pooled into ``block`` x ``block`` blocks (a block is set if any of its cells is),
    merged the same way, and every rectangle is shrunk to the True cells it contains; the
    union then covers every True cell and reaches at most ``block`` - 1 cells beyond them.
    """
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    occupied = np.asarray(occupied, dtype=bool)
    rows, cols = occupied.shape
    if block > 1:
        pooled_rows, pooled_cols = -(-rows // block), -(-cols // block)
        padded = np.zeros((pooled_rows * block, pooled_cols * block), dtype=bool)
        padded[:rows, :cols] = occupied
        pooled = padded.reshape(pooled_rows, block, pooled_cols, block).any(axis=(1, 3))
        return _shrink(occupied, merge_cells(pooled) * block)
    edges = np.diff(np.pad(occupied.astype(np.int8), ((0, 0), (1, 1))), axis=1)
    run_row, run_begin = np.nonzero(edges == 1)
    run_end = np.nonzero(edges == -1)[1]
    if len(run_row) == 0:
        return np.zeros((0, 4), dtype=int)
    # Sort runs by span, then row: runs to merge become consecutive.
    order = np.lexsort((run_row, run_end, run_begin))
    run_row, run_begin, run_end = run_row[order], run_begin[order], run_end[order]
    starts = np.ones(len(run_row), dtype=bool)
    starts[1:] = ((run_begin[1:] != run_begin[:-1]) | (run_end[1:] != run_end[:-1])
                  | (run_row[1:] != run_row[:-1] + 1))
    last = np.append(np.flatnonzero(starts)[1:] - 1, len(run_row) - 1)
    return np.stack([run_row[starts], run_row[last] + 1, run_begin[starts], run_end[starts]],
                    axis=1)


def _shrink(occupied: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """Each rectangle (clipped to the grid) shrunk to the bounding box of its True cells;
    rectangles without any are dropped."""
    rows, cols = occupied.shape
    out = []
    for r0, r1, c0, c1 in rects.tolist():
        cells = occupied[r0:min(r1, rows), c0:min(c1, cols)]
        row_hit = np.flatnonzero(cells.any(axis=1))
        col_hit = np.flatnonzero(cells.any(axis=0))
        if len(row_hit):
            out.append((r0 + row_hit[0], r0 + row_hit[-1] + 1, c0 + col_hit[0],
                        c0 + col_hit[-1] + 1))
    return np.array(out, dtype=int).reshape(-1, 4)
