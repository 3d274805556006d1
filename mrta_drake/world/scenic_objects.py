"""Objects placed in the hospital by a Scenic 3 program (the ``scenic`` extra).

A scenario's ``world.scenic`` names a Scenic program. ``add_scenic_objects`` samples one scene
of it for the scenario's seed and adds every object to the floor plan's obstacles, the world's
one obstacle source, so the plant, the costmap and planner, the controllers, the people and
Meshcat all see them. Without Scenic installed this module still imports; sampling raises an
``InputError`` saying how to install it.

The program runs in Scenic's 2D mode and starts with ``model mrta_drake.world.scenic_model``, which
defines the object classes (``Bed``, ``Cart``, ``Bookshelf``, ``Bin``) and these regions, set
from the scenario:

- ``free_space`` (Scenic's workspace): the floor plan's bounds less its obstacles and less a
  disk of each ``keep_clear`` circle (a robot's radius around its start);
- ``lanes``: where robots drive and wait (roadway edges, queue slots, room entries, service
  points, parking spots), widened by ``LANE_CLEARANCE`` + the largest robot radius each side;
- ``beside_lanes``: ``free_space`` less ``lanes``, the region objects must lie in unless they
  say otherwise (``with regionContainedIn workspace`` may block a corridor);
- ``places``: the floor plan's named places, name -> (x, y).

Scenic resamples until no object leaves its region or overlaps another. Each object becomes a
``Box`` of its width x length x height yawed by its heading (a Scenic heading is
counterclockwise from +y, the direction of ``length``: so yaw = heading and size = (width,
length)), or, with ``cylinder`` set, an upright ``Cylinder`` of diameter max(width, length).

Scenic draws from Python's and NumPy's global random generators: both are seeded with the
seed for the sampling and restored afterwards, so one seed gives one scene.

Units: metres, radians; world frame x east, y north.
"""

import dataclasses
import math
import random
from collections.abc import Mapping, Sequence

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import Scenario
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles

LANE_CLEARANCE = 0.15  # m beyond the largest robot radius kept free each side of a lane
MAX_ITERATIONS = 2000  # scenes Scenic may reject before giving up
_CIRCLE_SEGMENTS = 16  # per quarter circle, for circles as polygons
_MODEL_PARAMS = ("free_space", "lanes", "beside_lanes", "places")


def add_scenic_objects(floor_plan: FloorPlan, scenario: Scenario) -> FloorPlan:
    """``floor_plan`` with the objects of the scenario's Scenic program (``world.scenic``),
    sampled for its seed, added to its obstacles. Locations must have their points."""
    world = scenario.world
    for name in world.scenic_params:
        if name in _MODEL_PARAMS:
            raise InputError(scenario.source, f"world.scenic_params.{name}",
                             "is set by mrta-drake from the floor plan and scenario")
    robots = scenario.robots
    keep_clear = [(r.start[0], r.start[1], r.radius) for r in robots]
    half_width = LANE_CLEARANCE + max((r.radius for r in robots), default=0.0)
    objects = sample_objects(world.scenic, floor_plan, scenario.seed, keep_clear=keep_clear,
                             lanes=traffic_lines(scenario), lane_half_width=half_width,
                             params=world.scenic_params, file=scenario.source)
    return dataclasses.replace(
        floor_plan, obstacles=floor_plan.obstacles.added(objects.boxes, objects.cylinders))


def sample_objects(program: str, floor_plan: FloorPlan, seed: int, *,
                   keep_clear: Sequence[Sequence[float]] = (),
                   lanes: Sequence[np.ndarray] = (), lane_half_width: float = 0.0,
                   params: Mapping[str, object] | None = None,
                   file: str | None = None) -> Obstacles:
    """The objects of one scene of the Scenic ``program`` (a file) in ``floor_plan``, drawn
    with ``seed``: ``keep_clear`` circles (x, y, radius) stay free; ``lanes`` are polylines
    (k, 2) widened by ``lane_half_width`` m each side into the ``lanes`` region; ``params``
    override the program's ``param`` values. ``file`` (the scenario) is named in errors."""
    try:
        import scenic
        from scenic.core.distributions import RejectionException
        from scenic.core.regions import PolygonalRegion
    except ImportError:
        raise InputError(file, "world.scenic", "needs Scenic 3: pip install "
                         "'mrta-drake[scenic]' (or pip install scenic)") from None
    free = free_space(floor_plan, keep_clear)
    taken = lane_area(lanes, lane_half_width).intersection(free)
    model_params = {
        "free_space": PolygonalRegion(polygon=free),
        "lanes": PolygonalRegion(polygon=taken) if not taken.is_empty else None,
        "beside_lanes": PolygonalRegion(polygon=free.difference(taken)),
        "places": {name: tuple(xy) for name, xy in floor_plan.places.items()},
    }
    python_state, numpy_state = random.getstate(), np.random.get_state()
    random.seed(seed)
    np.random.seed(seed)
    try:
        try:
            scenario = scenic.scenarioFromFile(program, params=dict(params or {}) | model_params,
                                               mode2D=True)
        except Exception as error:  # the program is user input: any failure is its error
            raise InputError(program, None, _first_line(error)) from None
        try:
            scene, _ = scenario.generate(maxIterations=MAX_ITERATIONS, verbosity=0)
        except RejectionException:
            raise InputError(program, None, f"no scene met the program's requirements in "
                             f"{MAX_ITERATIONS} tries (seed {seed})") from None
    finally:
        random.setstate(python_state)
        np.random.set_state(numpy_state)
    return _obstacles(scene.objects)


def free_space(floor_plan: FloorPlan, keep_clear: Sequence[Sequence[float]] = ()):
    """The floor plan's free region as a shapely geometry: its bounds less every obstacle
    and every ``keep_clear`` circle (x, y, radius). Circles are circumscribed polygons, so
    the region never reaches into them."""
    from shapely.geometry import box

    x_min, x_max, y_min, y_max = floor_plan.bounds
    obstacles = floor_plan.obstacles
    taken = [footprint(o) for o in obstacles.boxes + obstacles.cylinders]
    taken += [_circle(c[:2], c[2]) for c in keep_clear]
    return box(x_min, y_min, x_max, y_max).difference(_union(taken))


def lane_area(lanes: Sequence[np.ndarray], half_width: float):
    """The polylines ``lanes`` (each (k, 2)) widened by ``half_width`` m each side, as one
    shapely geometry."""
    from shapely.geometry import LineString, Point

    shapes = [(Point(line[0]) if len(line) == 1 else LineString(line))
              .buffer(half_width, quad_segs=_CIRCLE_SEGMENTS) for line in lanes]
    return _union(shapes)


def footprint(obstacle: Box | Cylinder):
    """The shapely polygon an obstacle covers on the floor (circles circumscribed)."""
    from shapely import affinity
    from shapely.geometry import box

    if isinstance(obstacle, Cylinder):
        return _circle(obstacle.center, obstacle.radius)
    hx, hy = 0.5 * obstacle.size[0], 0.5 * obstacle.size[1]
    shape = affinity.rotate(box(-hx, -hy, hx, hy), obstacle.yaw, origin=(0.0, 0.0),
                            use_radians=True)
    return affinity.translate(shape, obstacle.center[0], obstacle.center[1])


def traffic_lines(scenario: Scenario) -> list[np.ndarray]:
    """Polylines (k, 2) robots drive or wait on: every roadway edge; per location, from its
    approach node along its queue (tail to head) and entry to its point, from its point back
    out to its exit node, and from its point to each parking spot. Locations need points."""
    nodes = scenario.roadways.nodes
    lines = [[nodes[a], nodes[b]] for a, b in scenario.roadways.edges]
    for location in scenario.locations:
        approach = [nodes[location.approach_node]] if location.approach_node else []
        leave = [nodes[location.exit_node]] if location.exit_node else []
        inward = [*location.queue[::-1], *location.entry]
        lines.append(approach + inward + [location.point])
        lines.append([location.point, *location.entry[::-1]] + leave)
        lines += [[location.point, spot] for spot in location.parking]
    return [np.array(line, dtype=float).reshape(-1, 2) for line in lines]


def _obstacles(objects) -> Obstacles:
    boxes, cylinders = [], []
    for k, obj in enumerate(objects):
        name = f"{type(obj).__name__.lower()}_{k}"
        center = (float(obj.position.x), float(obj.position.y))
        width, length, height = float(obj.width), float(obj.length), float(obj.height)
        if getattr(obj, "cylinder", False):
            cylinders.append(Cylinder(name, center, 0.5 * max(width, length), height))
        else:
            boxes.append(Box(name, center, (width, length), float(obj.heading), height))
    return Obstacles(tuple(boxes), tuple(cylinders))


def _circle(center, radius: float):
    from shapely.geometry import Point

    # Circumscribed: the polygon's edges touch the circle from outside.
    scale = 1.0 / math.cos(math.pi / (4 * _CIRCLE_SEGMENTS))
    return Point(center[0], center[1]).buffer(radius * scale, quad_segs=_CIRCLE_SEGMENTS)


def _union(shapes):
    from shapely.geometry import GeometryCollection
    from shapely.ops import unary_union

    return unary_union(shapes) if shapes else GeometryCollection()


def _first_line(error: Exception) -> str:
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}".rstrip(": ")
