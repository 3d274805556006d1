"""Floor plans: one building floor as obstacles, bounds and named places, and the loader of
our floor-plan files (format: ``floor_plan_format.FloorPlanFile``).

``load_floor_plan`` reads a file with the typed loader and turns it into ``Obstacles`` (the
world's one obstacle source): walls split at their doors into boxes, furniture into boxes
and cylinders. Any problem raises ``InputError`` naming the file, the field (e.g.
``walls[3].doors[0].width``) and the value.
"""

import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field

from mrta_drake.scenario.typed_yaml import load_typed, read_yaml
from mrta_drake.world.floor_plan_format import FloorPlanFile, FurnitureSpec, WallSpec
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid

_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class FloorPlan:
    """One floor of a building, however it was made (authored plan or imported map).

    ``bounds`` = (x_min, x_max, y_min, y_max) of the mapped area, m. ``obstacles`` are the
    walls and furniture. ``places`` maps names to world (x, y) points, m. ``source`` is the file
    the plan was loaded from. ``raw_grid`` is the occupancy the plan was imported from (ROS
    maps), None for authored plans. ``floors``: polygons ((x, y) vertices, m) of the floor
    robots may drive on, outside all of which the planner's costmap is an obstacle
    (``Costmap.from_obstacles``); empty: everywhere within ``bounds``.
    """

    name: str
    bounds: tuple[float, float, float, float]
    wall_height: float
    obstacles: Obstacles
    places: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    source: str = ""
    raw_grid: OccupancyGrid | None = None
    floors: tuple[tuple[tuple[float, float], ...], ...] = ()

    def occupancy(self, resolution: float = 0.05) -> OccupancyGrid:
        """The obstacles rasterized over ``bounds`` with square cells of ``resolution`` m."""
        return self.obstacles.rasterize(self.bounds, resolution)


def load_floor_plan(path) -> FloorPlan:
    """Reads and checks the floor-plan file at ``path`` (see ``FloorPlanFile``). A file read
    before and unchanged since (same size and modification time) gives the same ``FloorPlan``
    object again, its obstacles' compiled tables included: a run reads its floor plan twice
    (checking the scenario, building the stack), and parsing the hospital's takes ~0.15 s."""
    path = str(path)
    try:
        stat = os.stat(path)
    except OSError:
        return _load_floor_plan(path, None)  # the loader names the problem
    return _load_floor_plan(path, (os.path.abspath(path), stat.st_size, stat.st_mtime_ns))


@functools.lru_cache(maxsize=16)
def _load_floor_plan(path: str, version) -> FloorPlan:
    """``load_floor_plan`` of ``path`` as of ``version`` (the file's absolute path, size and
    modification time)."""
    spec = load_typed(read_yaml(path, "floor-plan file"), FloorPlanFile, path)
    boxes: list[Box] = []
    cylinders: list[Cylinder] = []
    for i, wall in enumerate(spec.walls):
        boxes += _wall_boxes(spec.wall_name(i), wall, spec.thickness_of(wall), spec.wall_height)
    for item in spec.furniture:
        shape_boxes, shape_cylinders = _furniture_shapes(item)
        boxes += shape_boxes
        cylinders += shape_cylinders
    return FloorPlan(name=spec.name, bounds=spec.bounds, wall_height=spec.wall_height,
                     obstacles=Obstacles(tuple(boxes), tuple(cylinders)),
                     places=dict(spec.places), source=path)


def _wall_boxes(name: str, wall: WallSpec, thickness: float, height: float) -> list[Box]:
    """The wall's pieces between its doors as boxes named ``name`` (``name_<k>`` when there
    are several); pieces reaching an end of the wall get half a thickness more there."""
    length = wall.length
    pieces, start = [], 0.0
    for lo, hi in sorted(wall.door_gaps(thickness)):
        pieces.append((start, lo))
        start = hi
    pieces.append((start, length))
    pieces = [(s, e) for s, e in pieces if e - s > _EPS]
    (ux, uy), (ax, ay) = wall.direction, wall.from_
    yaw = math.atan2(uy, ux)
    boxes = []
    for k, (s, e) in enumerate(pieces):
        s = s - 0.5 * thickness if s <= _EPS else s
        e = e + 0.5 * thickness if e >= length - _EPS else e
        mid = 0.5 * (s + e)
        boxes.append(Box(name=name if len(pieces) == 1 else f"{name}_{k}",
                         center=(ax + mid * ux, ay + mid * uy), size=(e - s, thickness),
                         yaw=yaw, height=height))
    return boxes


def _furniture_shapes(item: FurnitureSpec) -> tuple[list[Box], list[Cylinder]]:
    if item.box is not None:
        box = item.box
        return [Box(item.name, box.center, box.size, box.yaw, box.height)], []
    if item.cylinder is not None:
        cylinder = item.cylinder
        return [], [Cylinder(item.name, cylinder.center, cylinder.radius, cylinder.height)]
    arc = item.arc
    return arc_boxes(item.name, arc.center, arc.radius, arc.thickness, arc.start, arc.end,
                     arc.segments, arc.height), []


def arc_boxes(name: str, center, radius: float, thickness: float, start: float, end: float,
              segments: int, height: float) -> list[Box]:
    """An arc of centre-line ``radius`` (m) around ``center`` from angle ``start`` to ``end``
    (rad, counterclockwise) as ``segments`` tangent boxes ``thickness`` wide. Each box is long
    enough that neighbours touch at the outer edge, so the chain has no gaps."""
    step = (end - start) / segments
    length = 2.0 * (radius + 0.5 * thickness) * math.tan(0.5 * step)
    boxes = []
    for k in range(segments):
        angle = start + (k + 0.5) * step
        boxes.append(Box(name=f"{name}_{k}",
                         center=(center[0] + radius * math.cos(angle),
                                 center[1] + radius * math.sin(angle)),
                         size=(length, thickness), yaw=angle + 0.5 * math.pi, height=height))
    return boxes
