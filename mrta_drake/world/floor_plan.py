"""Floor plans: the project's own YAML format for one building floor, and its loader.

A floor plan is authored by hand: walls are segments with doors (gaps) in them, furniture is
boxes, cylinders and arcs, and places are named points. ``load_floor_plan`` turns it into
``Obstacles`` (the world's one obstacle source) plus the plan's bounds and places.

World frame: x east, y north, z up; lengths in metres, angles in radians (counterclockwise
from +x). Format::

    name: hospital_floor1                  # required
    bounds: [x_min, x_max, y_min, y_max]   # required; the mapped area
    wall_height: 2.5                       # optional, default 2.5
    wall_thickness: 0.15                   # optional default for every wall, default 0.15
    walls:                                 # optional
      - name: lobby_south                  # optional; default wall<i>
        from: [x, y]                       # centre-line end points
        to: [x, y]
        thickness: 0.15                    # optional, default wall_thickness
        doors:                             # optional; each door is a gap in the wall
          - {center: [x, y], width: 1.4}   # center lies on the wall; width along it
    furniture:                             # optional; each item has exactly one shape
      - {name: bed_1, box: {center: [x, y], size: [sx, sy], yaw: 0.0, height: 0.6}}
      - {name: planter, cylinder: {center: [x, y], radius: 0.3, height: 1.0}}
      - name: reception                    # an arc, built as a chain of boxes
        arc: {center: [x, y], radius: 3.3, thickness: 0.4, start: 0.0, end: 3.14,
              segments: 8, height: 1.1}
    places: {lobby: [0.0, 2.2]}            # optional named points

Walls become one box per piece between doors, ``thickness`` wide and ``wall_height`` tall. A
piece that reaches an end of its wall is extended by half the thickness there, so walls that
meet at a shared end point close their corner. A door's ``center`` may be off the centre line
by at most the wall's thickness; the gap is ``width`` long, centred on the projection of
``center`` onto the wall, and must lie within the wall. Defaults: box ``yaw`` 0, furniture
``height`` 1.0, arc ``segments`` 8. An arc's ``radius`` is that of its centre line and it runs
counterclockwise from ``start`` to ``end``; consecutive boxes meet at the outer edge.

Any problem raises ``InputError`` naming the file, the field (e.g. ``walls[3].doors[0].width``)
and the value.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_load

from mrta_drake.errors import InputError
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid

_DEFAULT_WALL_HEIGHT = 2.5
_DEFAULT_WALL_THICKNESS = 0.15
_DEFAULT_FURNITURE_HEIGHT = 1.0
_DEFAULT_ARC_SEGMENTS = 8
_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class FloorPlan:
    """One floor of a building, however it was made (authored plan or imported map).

    ``bounds`` = (x_min, x_max, y_min, y_max) of the mapped area, m. ``obstacles`` are the
    walls and furniture. ``places`` maps names to world (x, y) points, m. ``source`` is the file
    the plan was loaded from. ``raw_grid`` is the occupancy the plan was imported from (ROS
    maps), None for authored plans.
    """

    name: str
    bounds: tuple[float, float, float, float]
    wall_height: float
    obstacles: Obstacles
    places: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    source: str = ""
    raw_grid: OccupancyGrid | None = None

    def occupancy(self, resolution: float = 0.05) -> OccupancyGrid:
        """The obstacles rasterized over ``bounds`` with square cells of ``resolution`` m."""
        return self.obstacles.rasterize(self.bounds, resolution)


def load_floor_plan(path) -> FloorPlan:
    """Reads and validates a floor-plan YAML file (see the module docstring)."""
    path = str(path)
    raw = read_yaml(path)
    r = FieldReader(path)
    top = r.mapping(raw, "", required=("name", "bounds"),
                    optional=("wall_height", "wall_thickness", "walls", "furniture", "places"))
    name = r.string(top["name"], "name")
    bounds = _bounds(r, top["bounds"])
    wall_height = r.number(top.get("wall_height", _DEFAULT_WALL_HEIGHT), "wall_height",
                           positive=True)
    thickness = r.number(top.get("wall_thickness", _DEFAULT_WALL_THICKNESS), "wall_thickness",
                         positive=True)
    boxes: list[Box] = []
    cylinders: list[Cylinder] = []
    names: dict[str, str] = {}  # wall or furniture name -> where it was defined

    def claim(name: str, where: str) -> None:
        if name in names:
            raise InputError(path, f"{where}.name", f"'{name}' is already used by {names[name]}")
        names[name] = where

    for i, item in enumerate(r.sequence(top.get("walls", []), "walls")):
        wall_boxes = _wall(r, item, f"walls[{i}]", i, bounds, thickness, wall_height)
        claim(item.get("name", f"wall{i}"), f"walls[{i}]")
        boxes += wall_boxes
    for i, item in enumerate(r.sequence(top.get("furniture", []), "furniture")):
        shape_boxes, shape_cylinders = _furniture(r, item, f"furniture[{i}]", bounds)
        claim(item["name"], f"furniture[{i}]")
        boxes += shape_boxes
        cylinders += shape_cylinders
    places = {}
    for key, value in r.mapping(top.get("places", {}), "places", optional=None).items():
        where = f"places.{key}"
        r.string(key, where)
        places[key] = _inside(r, r.point(value, where), where, bounds)
    return FloorPlan(name=name, bounds=bounds, wall_height=wall_height,
                     obstacles=Obstacles(tuple(boxes), tuple(cylinders)), places=places,
                     source=path)


def read_yaml(path: str):
    """The untyped content of YAML file ``path``; a missing, malformed or empty file raises
    ``InputError``."""
    if not Path(path).is_file():
        raise InputError(path, None, "file not found")
    try:
        content = yaml_load(filename=path)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(path, None, f"invalid YAML{at}: {e.problem or e.context}") from None
    except yaml.YAMLError as e:
        raise InputError(path, None, f"invalid YAML: {e}") from None
    if content is None:
        raise InputError(path, None, "the file is empty")
    return content


def _bounds(r: "FieldReader", value) -> tuple[float, float, float, float]:
    values = r.numbers(value, "bounds", 4)
    x_min, x_max, y_min, y_max = values
    if not (x_min < x_max and y_min < y_max):
        raise InputError(r.path, "bounds", f"need x_min < x_max and y_min < y_max, got "
                         f"{list(values)}")
    return values


def _inside(r: "FieldReader", point, where, bounds):
    x_min, x_max, y_min, y_max = bounds
    if not (x_min - _EPS <= point[0] <= x_max + _EPS and y_min - _EPS <= point[1] <= y_max + _EPS):
        raise InputError(r.path, where, f"{list(point)} is outside bounds {list(bounds)}")
    return point


def _wall(r: "FieldReader", item, where, index, bounds, default_thickness, height) -> list[Box]:
    wall = r.mapping(item, where, required=("from", "to"), optional=("name", "thickness", "doors"))
    name = r.string(wall.get("name", f"wall{index}"), f"{where}.name")
    a = _inside(r, r.point(wall["from"], f"{where}.from"), f"{where}.from", bounds)
    b = _inside(r, r.point(wall["to"], f"{where}.to"), f"{where}.to", bounds)
    thickness = r.number(wall.get("thickness", default_thickness), f"{where}.thickness",
                         positive=True)
    length = math.dist(a, b)
    if length <= _EPS:
        raise InputError(r.path, f"{where}.to", f"{list(b)} equals 'from': a wall needs length")
    ux, uy = (b[0] - a[0]) / length, (b[1] - a[1]) / length
    gaps = []
    for k, door_item in enumerate(r.sequence(wall.get("doors", []), f"{where}.doors")):
        door_where = f"{where}.doors[{k}]"
        door = r.mapping(door_item, door_where, required=("center", "width"))
        center = r.point(door["center"], f"{door_where}.center")
        width = r.number(door["width"], f"{door_where}.width", positive=True)
        if width > length + _EPS:
            raise InputError(r.path, f"{door_where}.width", f"{width:g} m is wider than its "
                             f"wall ({length:g} m long)")
        dx, dy = center[0] - a[0], center[1] - a[1]
        offset = abs(-uy * dx + ux * dy)
        along = ux * dx + uy * dy
        if offset > thickness + _EPS:
            raise InputError(r.path, f"{door_where}.center", f"{list(center)} is {offset:.3g} m "
                             f"off its wall from {list(a)} to {list(b)} (at most {thickness:g})")
        lo, hi = along - 0.5 * width, along + 0.5 * width
        if lo < -_EPS or hi > length + _EPS:
            raise InputError(r.path, f"{door_where}.center", f"{list(center)}: the door spans "
                             f"{lo:.3g}..{hi:.3g} m along its wall, which is {length:g} m long")
        for other_lo, other_hi, other in gaps:
            if lo < other_hi - _EPS and other_lo < hi - _EPS:
                raise InputError(r.path, f"{door_where}.center",
                                 f"{list(center)}: the door overlaps doors[{other}]")
        gaps.append((lo, hi, k))
    # Pieces between doors, as (start, end) distances along the wall.
    pieces, start = [], 0.0
    for lo, hi, _ in sorted(gaps):
        pieces.append((start, lo))
        start = hi
    pieces.append((start, length))
    pieces = [(s, e) for s, e in pieces if e - s > _EPS]
    boxes = []
    yaw = math.atan2(uy, ux)
    for k, (s, e) in enumerate(pieces):
        s = s - 0.5 * thickness if s <= _EPS else s
        e = e + 0.5 * thickness if e >= length - _EPS else e
        mid = 0.5 * (s + e)
        boxes.append(Box(name=name if len(pieces) == 1 else f"{name}_{k}",
                         center=(a[0] + mid * ux, a[1] + mid * uy), size=(e - s, thickness),
                         yaw=yaw, height=height))
    return boxes


def _furniture(r: "FieldReader", item, where, bounds) -> tuple[list[Box], list[Cylinder]]:
    shapes = ("box", "cylinder", "arc")
    entry = r.mapping(item, where, required=("name",), optional=shapes)
    name = r.string(entry["name"], f"{where}.name")
    given = [s for s in shapes if s in entry]
    if len(given) != 1:
        raise InputError(r.path, where, f"needs exactly one of {', '.join(shapes)}, got "
                         f"{given or 'none'}")
    kind = given[0]
    where = f"{where}.{kind}"
    if kind == "box":
        spec = r.mapping(entry[kind], where, required=("center", "size"),
                         optional=("yaw", "height"))
        center = _inside(r, r.point(spec["center"], f"{where}.center"), f"{where}.center", bounds)
        size = r.numbers(spec["size"], f"{where}.size", 2, positive=True)
        yaw = r.number(spec.get("yaw", 0.0), f"{where}.yaw")
        height = r.number(spec.get("height", _DEFAULT_FURNITURE_HEIGHT), f"{where}.height",
                          positive=True)
        return [Box(name, center, size, yaw, height)], []
    if kind == "cylinder":
        spec = r.mapping(entry[kind], where, required=("center", "radius"), optional=("height",))
        center = _inside(r, r.point(spec["center"], f"{where}.center"), f"{where}.center", bounds)
        radius = r.number(spec["radius"], f"{where}.radius", positive=True)
        height = r.number(spec.get("height", _DEFAULT_FURNITURE_HEIGHT), f"{where}.height",
                          positive=True)
        return [], [Cylinder(name, center, radius, height)]
    spec = r.mapping(entry[kind], where, required=("center", "radius", "thickness", "start", "end"),
                     optional=("segments", "height"))
    center = _inside(r, r.point(spec["center"], f"{where}.center"), f"{where}.center", bounds)
    radius = r.number(spec["radius"], f"{where}.radius", positive=True)
    thickness = r.number(spec["thickness"], f"{where}.thickness", positive=True)
    if thickness >= 2.0 * radius:
        raise InputError(r.path, f"{where}.thickness", f"{thickness:g} must be less than twice "
                         f"the radius ({radius:g})")
    start = r.number(spec["start"], f"{where}.start")
    end = r.number(spec["end"], f"{where}.end")
    if not 0.0 < end - start <= 2.0 * math.pi + _EPS:
        raise InputError(r.path, f"{where}.end", f"{end:g} must be in (start, start + 2 pi], "
                         f"start is {start:g}")
    segments = r.integer(spec.get("segments", _DEFAULT_ARC_SEGMENTS), f"{where}.segments",
                         minimum=1)
    height = r.number(spec.get("height", _DEFAULT_FURNITURE_HEIGHT), f"{where}.height",
                      positive=True)
    return arc_boxes(name, center, radius, thickness, start, end, segments, height), []


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


class FieldReader:
    """Typed access to the untyped values of YAML file ``path``; every failure is an
    ``InputError`` naming the file and the field path (e.g. ``walls[3].doors[0].width``)."""

    def __init__(self, path: str):
        self.path = path

    def fail(self, where: str, message: str):
        raise InputError(self.path, where or None, message)

    def mapping(self, value, where, required=(), optional=()) -> dict:
        """``value`` as a dict with all ``required`` keys and no keys outside ``required`` and
        ``optional`` (any keys when ``optional`` is None)."""
        if value is None and not required:
            return {}
        if not isinstance(value, dict):
            self.fail(where, f"expected a mapping, got {value!r}")
        prefix = f"{where}." if where else ""
        for key in value:
            if optional is not None and key not in required and key not in optional:
                allowed = ", ".join((*required, *optional))
                self.fail(f"{prefix}{key}", f"unknown key (allowed: {allowed})")
        for key in required:
            if key not in value:
                self.fail(f"{prefix}{key}", "missing")
        return value

    def sequence(self, value, where) -> list:
        if value is None:
            return []
        if not isinstance(value, list):
            self.fail(where, f"expected a list, got {value!r}")
        return value

    def string(self, value, where) -> str:
        if not isinstance(value, str) or not value:
            self.fail(where, f"expected a non-empty string, got {value!r}")
        return value

    def number(self, value, where, positive=False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(where, f"expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            self.fail(where, f"must be finite, got {value!r}")
        if positive and value <= 0.0:
            self.fail(where, f"must be > 0, got {value:g}")
        return value

    def integer(self, value, where, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(where, f"expected an integer, got {value!r}")
        if value < minimum:
            self.fail(where, f"must be >= {minimum}, got {value}")
        return value

    def numbers(self, value, where, count: int, positive=False) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != count:
            self.fail(where, f"expected a list of {count} numbers, got {value!r}")
        return tuple(self.number(v, f"{where}[{i}]", positive) for i, v in enumerate(value))

    def point(self, value, where) -> tuple[float, float]:
        return self.numbers(value, where, 2)
