"""One level of an Open-RMF building as this project's world: a ``FloorPlan`` of boxes and
cylinders, made in code.

- Walls become boxes ``wall_thickness`` wide and ``wall_height`` tall. A door lying along a
  wall is a gap in it; a wall end that is not a door jamb is extended by half the thickness
  so that walls meeting there close their corner.
- Static models become furniture: a box or a cylinder from ``rmf_footprints``, else a
  cylinder of ``model_radius``; a model whose footprint comes nearer than
  ``lane_clearance`` to a robot lane is left out (the lanes are what robots must be able to
  drive; ``LevelWorld.left_out`` names them).
- Each lift whose shaft passes the level is walled in around its cabin, with a gap for each
  cabin door that opens on this level.
- Bounds: the floor polygons (else the walls), grown to hold every lane and lift, plus
  ``bounds_margin``.
- Places: the level's named vertices, those on lanes of the chosen graph first (a name
  may be reused in other graphs).

Metres, world frame (x east, y north).
"""

import math
from dataclasses import dataclass

import numpy as np

from mrta_drake.errors import InputError, require_non_negative, require_positive
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles
from mrta_drake.world.rmf_building import Building, Level, Lift, Model
from mrta_drake.world.rmf_footprints import footprint
from mrta_drake.world.segment_distances import segment_distances

_ON_WALL = 0.05  # m: a door end this near a wall's centre line lies on it


@dataclass(frozen=True)
class BuildingWorldParams:
    """How a level becomes a world. ``wall_thickness`` 0.1 m and ``wall_height`` 2.5 m are
    what Open-RMF's generator builds; ``model_radius`` (m) is the cylinder of a model whose
    footprint is unknown, ``model_height`` (m) the height of every model;
    ``lane_clearance`` (m): a model nearer than this to a robot lane's centre line is
    left out (default: a 0.22 m robot plus 0.13 m); ``bounds_margin`` (m) is added around
    the mapped area."""

    wall_thickness: float = 0.1
    wall_height: float = 2.5
    model_radius: float = 0.3
    model_height: float = 1.0
    lane_clearance: float = 0.35
    bounds_margin: float = 1.0

    def __post_init__(self):
        require_positive(self, "wall_thickness", "wall_height", "model_radius", "model_height",
                         unit=" m")
        require_non_negative(self, "lane_clearance", "bounds_margin", unit=" m")


@dataclass(frozen=True, eq=False)
class LevelWorld:
    """A level as a ``floor_plan``, and the models ``left_out`` because they come too near
    a lane (as "name (model_name) at [x, y]")."""

    floor_plan: FloorPlan
    left_out: tuple[str, ...]


def level_world(building: Building, level_name: str, graph: int = 0,
                params: BuildingWorldParams = BuildingWorldParams()) -> LevelWorld:
    """The world of level ``level_name`` of ``building`` (places: graph ``graph`` first)."""
    level = building.level(level_name)
    boxes = _walls(level, params)
    for lift in building.lifts_through(level_name):
        boxes += _shaft(lift, lift.level_doors.get(level_name, ()), params)
    walls = Obstacles(tuple(boxes))
    lanes = _lane_segments(level)
    furniture, left_out = [], []
    for k, model in enumerate(level.models):
        shape = _model_shape(model, f"{model.name or 'model'}_{k}", params)
        if shape is None:
            continue
        if _nearest_lane(shape, lanes) < params.lane_clearance:
            left_out.append(f"{model.name} ({model.model_name}) at "
                            f"[{model.xy[0]:.2f}, {model.xy[1]:.2f}]")
        else:
            furniture.append(shape)
    obstacles = walls.added(boxes=[s for s in furniture if isinstance(s, Box)],
                            cylinders=[s for s in furniture if isinstance(s, Cylinder)])
    floor_plan = FloorPlan(
        name=f"{building.name}_{level_name}", bounds=_bounds(building, level, walls, params),
        wall_height=params.wall_height, obstacles=obstacles, places=_places(level, graph),
        source=building.source)
    return LevelWorld(floor_plan, tuple(left_out))


def _walls(level: Level, params: BuildingWorldParams) -> list[Box]:
    doors = [(np.array(level.point(d.start)), np.array(level.point(d.end))) for d in level.doors]
    jambs = [end for door in doors for end in door]
    boxes = []
    for k, wall in enumerate(level.walls):
        a, b = np.array(level.point(wall.start)), np.array(level.point(wall.end))
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        gaps = []
        for p, q in doors:
            if _off_line(p, a, u) <= _ON_WALL and _off_line(q, a, u) <= _ON_WALL:
                lo, hi = sorted((float((p - a) @ u), float((q - a) @ u)))
                if hi > 0 and lo < length:
                    gaps.append((max(lo, 0.0), min(hi, length)))
        extend = [0.0 if any(np.linalg.norm(end - j) <= _ON_WALL for j in jambs)
                  else 0.5 * params.wall_thickness for end in (a, b)]
        boxes += _pieces(f"wall{k}", a, u, length, gaps, extend, params.wall_thickness,
                         params.wall_height)
    return boxes


def _off_line(p, a, u) -> float:
    """Distance of point ``p`` from the line through ``a`` along unit ``u``."""
    d = p - a
    return abs(float(d[0] * u[1] - d[1] * u[0]))


def _pieces(name, a, u, length, gaps, extend, thickness, height) -> list[Box]:
    """Boxes along the segment from ``a`` (unit direction ``u``, ``length`` m) between the
    ``gaps`` (start, end distances along it), ends extended by ``extend`` (m, at a and b)."""
    pieces, start = [], -extend[0]
    for lo, hi in sorted(gaps):
        pieces.append((start, lo))
        start = max(start, hi)
    pieces.append((start, length + extend[1]))
    pieces = [(s, e) for s, e in pieces if e - s > 1e-6]
    yaw = math.atan2(u[1], u[0])
    return [Box(name if len(pieces) == 1 else f"{name}_{k}",
                (float(a[0] + 0.5 * (s + e) * u[0]), float(a[1] + 0.5 * (s + e) * u[1])),
                (e - s, thickness), yaw, height)
            for k, (s, e) in enumerate(pieces)]


def _shaft(lift: Lift, open_doors, params: BuildingWorldParams) -> list[Box]:
    """Walls around ``lift``'s cabin (0.05 m clear of it), with a gap for each of
    ``open_doors`` in the face nearest the door."""
    t = params.wall_thickness
    half = (0.5 * lift.width + 0.05 + 0.5 * t, 0.5 * lift.depth + 0.05 + 0.5 * t)
    # Faces as (start corner, direction) in the cabin frame, counterclockwise from -y.
    corners = [(-half[0], -half[1]), (half[0], -half[1]), (half[0], half[1]),
               (-half[0], half[1])]
    boxes = []
    for k in range(4):
        a, b = np.array(corners[k]), np.array(corners[(k + 1) % 4])
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        gaps = []
        for door in (lift.doors[name] for name in open_doors):
            if _face_of(door.xy, lift) == k:
                along = float((np.array(door.xy) - a) @ u)
                gaps.append((along - 0.5 * door.width, along + 0.5 * door.width))
        for box in _pieces(f"{lift.name}_shaft{k}", a, u, length, gaps, (0.5 * t, 0.5 * t),
                           t, params.wall_height):
            boxes.append(Box(box.name, lift.to_world(box.center), box.size,
                             box.yaw + lift.yaw, box.height))
    return boxes


def _face_of(local, lift: Lift) -> int:
    """Which cabin face (0 -y, 1 +x, 2 +y, 3 -x) is nearest the cabin-frame point
    ``local``."""
    x, y = local[0] / lift.width, local[1] / lift.depth
    if abs(y) >= abs(x):
        return 0 if y < 0 else 2
    return 1 if x > 0 else 3


def _model_shape(model: Model, name: str, params: BuildingWorldParams):
    """The obstacle of a static model (a ``Box`` or ``Cylinder``), None if it is none."""
    if not model.static:
        return None
    try:
        shape = footprint(model.model_name)
    except KeyError:
        shape = params.model_radius
    if shape is None:
        return None
    if isinstance(shape, tuple):
        return Box(name, model.xy, shape, model.yaw, params.model_height)
    return Cylinder(name, model.xy, float(shape), params.model_height)


def _lane_segments(level: Level) -> np.ndarray:
    """(n, 2, 2) end points of every robot lane of the level (all graphs)."""
    return np.array([[level.point(lane.start), level.point(lane.end)] for lane in level.lanes],
                    dtype=float).reshape(-1, 2, 2)


def _nearest_lane(shape, segments: np.ndarray) -> float:
    """Distance (m) from the obstacle ``shape`` to the nearest of the lane ``segments``
    (n, 2, 2); 0 when one crosses it, inf without lanes."""
    if not len(segments):
        return math.inf
    if isinstance(shape, Cylinder):
        return float(segment_distances(shape.center, segments[:, 0], segments[:, 1]).min()
                     - shape.radius)
    c, s = math.cos(shape.yaw), math.sin(shape.yaw)
    hx, hy = 0.5 * shape.size[0], 0.5 * shape.size[1]
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    corners = shape.center + local @ np.array([[c, s], [-s, c]])
    from_corners = segment_distances(corners, segments[:, 0], segments[:, 1]).min()
    ends = segments.reshape(-1, 2)
    from_ends = Obstacles((shape,)).signed_distance(ends).min()
    edges = np.stack([corners, np.roll(corners, -1, axis=0)], axis=1)
    if from_ends <= 0 or _any_crossing(edges, segments):
        return 0.0
    return float(min(from_corners, from_ends))


def _any_crossing(first: np.ndarray, second: np.ndarray) -> bool:
    """Whether any segment of ``first`` (k, 2, 2) properly crosses any of ``second``
    (n, 2, 2)."""
    def side(p, q, r):  # sign of the turn p -> q -> r, broadcast
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    p, q = first[:, None, 0], first[:, None, 1]
    r, s = second[None, :, 0], second[None, :, 1]
    return bool(np.any((side(p, q, r) * side(p, q, s) < 0) & (side(r, s, p) * side(r, s, q) < 0)))


def _bounds(building: Building, level: Level, walls: Obstacles,
            params: BuildingWorldParams) -> tuple[float, float, float, float]:
    points = [level.point(i) for floor in level.floors for i in floor.vertices]
    if not points and len(walls):
        x0, x1, y0, y1 = walls.bounds()
        points = [(x0, y0), (x1, y1)]
    points += [level.point(i) for lane in level.lanes for i in (lane.start, lane.end)]
    for lift in building.lifts_through(level.name):
        reach = 0.5 * math.hypot(lift.width, lift.depth) + 0.2
        points += [(lift.xy[0] - reach, lift.xy[1] - reach), (lift.xy[0] + reach,
                                                              lift.xy[1] + reach)]
    if not points:
        raise InputError(building.source, f"levels.{level.name}",
                         "has no floors, walls or lanes: nothing to make a world of")
    xy = np.array(points, dtype=float)
    m = params.bounds_margin
    return (float(xy[:, 0].min() - m), float(xy[:, 0].max() + m),
            float(xy[:, 1].min() - m), float(xy[:, 1].max() + m))


def _places(level: Level, graph: int) -> dict[str, tuple[float, float]]:
    on_graph = {i for lane in level.lanes if lane.graph == graph for i in (lane.start, lane.end)}
    places = {}
    for first in (True, False):
        for i, vertex in enumerate(level.vertices):
            if vertex.name and (i in on_graph) == first and vertex.name not in places:
                places[vertex.name] = vertex.xy
    return places
