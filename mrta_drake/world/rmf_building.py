"""Open-RMF building maps (``*.building.yaml``) read into a frozen model in metres.

``load_building(path)`` reads the file, checks it and converts every position to metres in
the world frame (x east, y north; see ``rmf_coordinates`` for the three coordinate systems).
The format is described in docs/worlds.md ("Open-RMF buildings"). Edges (lanes, walls,
doors, measurements, human lanes) keep their vertex indices into their level's ``vertices``.
Parameters ``[code, value]`` are coerced by their code (1 string, 2 int, 3 double, 4 bool).

Any problem raises ``InputError`` naming the file, the item (e.g. ``levels.L1.lanes[3]``) and
the value.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

from mrta_drake.errors import InputError
from mrta_drake.scenario.typed_yaml import read_yaml
from mrta_drake.world.rmf_coordinates import CoordinateSystem, level_transforms
from mrta_drake.world.segment_distances import segment_distances

ParamValue = bool | int | float | str
PARAM_TYPES = {1: "string", 2: "int", 3: "double", 4: "bool"}
DOOR_ON_WALL_TOLERANCE = 0.05  # m: how far a door end may be from a wall and still be on it


@dataclass(frozen=True)
class Vertex:
    """A named or unnamed point (``name`` "" when unnamed) at ``xy`` (m), with its
    parameters (``is_charger``, ``pickup_dispenser``, ...)."""

    xy: tuple[float, float]
    name: str = ""
    params: Mapping[str, ParamValue] = field(default_factory=lambda: MappingProxyType({}))

    def flag(self, key: str) -> bool:
        """Whether the boolean parameter ``key`` is present and true."""
        return self.params.get(key) is True


@dataclass(frozen=True)
class Edge:
    """A segment between two vertices of its level (indices ``start``, ``end``)."""

    start: int
    end: int
    params: Mapping[str, ParamValue] = field(default_factory=lambda: MappingProxyType({}))


@dataclass(frozen=True)
class Lane(Edge):
    """A robot lane of navigation graph ``graph``, two-way when ``bidirectional``."""

    graph: int = 0
    bidirectional: bool = True


@dataclass(frozen=True)
class Door(Edge):
    """A door between its two jambs: ``name`` is unique in the building; ``kind`` is
    hinged, double_hinged, sliding or double_sliding."""

    name: str = ""
    kind: str = ""


@dataclass(frozen=True)
class Measurement(Edge):
    """A measured ``distance`` (m) between two vertices: what scales a drawing."""

    distance: float = 0.0


@dataclass(frozen=True)
class HumanLane(Edge):
    """A lane people walk (crowd simulation), ``width`` m wide."""

    width: float = 0.0


@dataclass(frozen=True)
class Floor:
    """A floor polygon: vertex indices in polygon order."""

    vertices: tuple[int, ...]
    params: Mapping[str, ParamValue] = field(default_factory=lambda: MappingProxyType({}))


@dataclass(frozen=True)
class Fiducial:
    """A named point used to align levels, at ``xy`` (m)."""

    name: str
    xy: tuple[float, float]


@dataclass(frozen=True)
class Model:
    """A placed model: instance ``name``, Fuel ``model_name`` ("Owner/Model"), at ``xy``
    (m), ``z`` m above the ground, ``yaw`` rad counterclockwise; ``static`` ones do not
    move."""

    name: str
    model_name: str
    xy: tuple[float, float]
    z: float = 0.0
    yaw: float = 0.0
    static: bool = True


@dataclass(frozen=True)
class Level:
    """One floor of the building at ``elevation`` m."""

    name: str
    elevation: float
    vertices: tuple[Vertex, ...]
    lanes: tuple[Lane, ...] = ()
    walls: tuple[Edge, ...] = ()
    doors: tuple[Door, ...] = ()
    floors: tuple[Floor, ...] = ()
    models: tuple[Model, ...] = ()
    fiducials: tuple[Fiducial, ...] = ()
    measurements: tuple[Measurement, ...] = ()
    human_lanes: tuple[HumanLane, ...] = ()

    def point(self, index: int) -> tuple[float, float]:
        """The position (m) of vertex ``index``."""
        return self.vertices[index].xy

    def graphs(self) -> tuple[int, ...]:
        """The navigation graph indices the level's lanes use, ascending."""
        return tuple(sorted({lane.graph for lane in self.lanes}))


@dataclass(frozen=True)
class LiftDoor:
    """A cabin door at ``xy`` (m, in the cabin's frame: x along its width, y along its
    depth), ``width`` m wide; ``door_type`` 1 single sliding, 2 double sliding, 3/4
    telescopic."""

    name: str
    xy: tuple[float, float]
    width: float
    door_type: int = 2


@dataclass(frozen=True)
class Lift:
    """A lift cabin centred at ``xy`` (m), turned by ``yaw`` (rad), ``width`` x ``depth``
    m; ``level_doors`` names, per level it serves, the cabin doors that open there. It runs
    between the elevations of ``lowest_floor`` and ``highest_floor``."""

    name: str
    xy: tuple[float, float]
    yaw: float
    width: float
    depth: float
    doors: Mapping[str, LiftDoor]
    level_doors: Mapping[str, tuple[str, ...]]
    reference_floor: str
    initial_floor: str
    lowest_floor: str
    highest_floor: str

    def to_world(self, local) -> tuple[float, float]:
        """A point (m) of the cabin frame in the world frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return (self.xy[0] + c * local[0] - s * local[1],
                self.xy[1] + s * local[0] + c * local[1])


@dataclass(frozen=True)
class Building:
    """A building read from ``source``: its levels in file order (the first, or
    ``reference_level``, fixes the frame), its lifts, and the coordinate system the file
    was drawn in."""

    name: str
    source: str
    coordinate_system: CoordinateSystem
    reference_level: str
    levels: Mapping[str, Level]
    lifts: Mapping[str, Lift]

    def level(self, name: str) -> Level:
        """Level ``name``; InputError naming the levels there are."""
        if name not in self.levels:
            raise InputError(self.source, "levels", f"no level {name!r} (levels: "
                             f"{', '.join(self.levels)})")
        return self.levels[name]

    def lifts_through(self, level: str) -> tuple[Lift, ...]:
        """The lifts whose shaft passes ``level`` (its elevation within their range)."""
        height = self.levels[level].elevation
        return tuple(
            lift for lift in self.lifts.values()
            if self.levels[lift.lowest_floor].elevation - 1e-9 <= height
            <= self.levels[lift.highest_floor].elevation + 1e-9)


def load_building(path) -> Building:
    """Read and check an Open-RMF ``.building.yaml`` file, positions in metres."""
    path = str(path)
    raw = read_yaml(path, "building file")
    return _Parser(path).building(raw)


class _Parser:
    """Reads the raw YAML of one building file; every failure is an ``InputError``."""

    def __init__(self, path: str):
        self.path = path

    def fail(self, where: str, message: str):
        raise InputError(self.path, where or None, message)

    def check_mapped(self, raw: Mapping[str, Level], moved: Mapping[str, Level],
                     system: CoordinateSystem) -> None:
        """Every position of ``moved`` (metres) is finite: a WGS84 latitude beyond the
        poles, e.g., projects to infinity."""
        for name, level in moved.items():
            for kind in ("vertices", "models", "fiducials"):
                for i, item in enumerate(getattr(level, kind)):
                    if not all(math.isfinite(c) for c in item.xy):
                        given = list(getattr(raw[name], kind)[i].xy)
                        self.fail(f"levels.{name}.{kind}[{i}]", f"{_short(given)} lies "
                                  f"outside the range of the {system.kind} coordinates")

    # --- Values ------------------------------------------------------------------------

    def mapping(self, value, where) -> dict:
        if value is None:
            return {}
        if not isinstance(value, dict):
            self.fail(where, f"expected a mapping, got {_short(value)}")
        return value

    def sequence(self, value, where) -> list:
        if value is None:
            return []
        if not isinstance(value, list):
            self.fail(where, f"expected a list, got {_short(value)}")
        return value

    def number(self, value, where, positive=False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value):
            self.fail(where, f"expected a number, got {_short(value)}")
        if positive and not value > 0:
            self.fail(where, f"must be > 0, got {value}")
        return float(value)

    def text(self, value, where) -> str:
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            self.fail(where, f"expected a name, got {_short(value)}")
        return str(value)

    def params(self, value, where) -> Mapping[str, ParamValue]:
        """Parameters ``{key: [code, value]}`` with each value coerced by its code."""
        result = {}
        for key, entry in self.mapping(value, where).items():
            here = f"{where}.{key}"
            if not isinstance(entry, list) or len(entry) != 2:
                self.fail(here, f"expected [type, value], got {_short(entry)}")
            result[str(key)] = self.param(entry[0], entry[1], here)
        return MappingProxyType(result)

    def param(self, code, value, where) -> ParamValue:
        if not isinstance(code, int) or isinstance(code, bool) or code not in PARAM_TYPES:
            known = ", ".join(f"{k} {name}" for k, name in PARAM_TYPES.items())
            self.fail(where, f"unknown parameter type {_short(code)} (known: {known})")
        kind = PARAM_TYPES[code]
        if kind == "string" and not isinstance(value, bool | list | dict) and value is not None:
            return str(value)
        if kind == "int" and isinstance(value, int | float) and not isinstance(value, bool) \
                and float(value).is_integer():
            return int(value)
        if kind == "double" and isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        if kind == "bool":
            if isinstance(value, bool):
                return value
            if value in (0, 1):
                return bool(value)
        self.fail(where, f"{_short(value)} is not a {kind} (type {code})")

    # --- Building ----------------------------------------------------------------------

    def building(self, raw) -> Building:
        top = self.mapping(raw, "")
        name = self.text(top.get("name", top.get("building_name", "")), "name")
        levels_raw = self.mapping(top.get("levels"), "levels")
        if not levels_raw:
            self.fail("levels", "missing or empty: a building needs at least one level")
        levels = {str(k): self.level(str(k), v) for k, v in levels_raw.items()}
        reference = self.text(top.get("reference_level_name", next(iter(levels))),
                              "reference_level_name")
        if reference not in levels:
            self.fail("reference_level_name", f"{reference!r} is not a level (levels: "
                      f"{', '.join(levels)})")
        system = self.coordinate_system(top)
        raw_lifts = self.mapping(top.get("lifts"), "lifts")
        lifts = {str(k): self.lift(str(k), v, levels) for k, v in raw_lifts.items()}
        self.check_door_names(levels)
        transforms = level_transforms(system, levels, reference, self.path)
        moved = {k: _moved(level, transforms[k]) for k, level in levels.items()}
        self.check_mapped(levels, moved, system)
        levels = moved
        lifts = {k: replace(lift, xy=transforms[lift.reference_floor].point(lift.xy))
                 for k, lift in lifts.items()}
        for level in levels.values():
            self.check_geometry(level)
        return Building(name, self.path, system, reference, MappingProxyType(levels),
                        MappingProxyType(lifts))

    def coordinate_system(self, top) -> CoordinateSystem:
        kind = self.text(top.get("coordinate_system", "reference_image"), "coordinate_system")
        params = self.params(top.get("parameters"), "parameters")
        try:
            return CoordinateSystem.of(kind, params)
        except ValueError as error:
            self.fail("coordinate_system" if kind not in CoordinateSystem.KINDS
                      else "parameters", str(error))

    def level(self, name: str, raw) -> Level:
        where = f"levels.{name}"
        level = self.mapping(raw, where)
        vertices = tuple(self.vertex(v, f"{where}.vertices[{i}]")
                         for i, v in enumerate(self.sequence(level.get("vertices"),
                                                             f"{where}.vertices")))
        count = len(vertices)

        def edges(key):
            for i, item in enumerate(self.sequence(level.get(key), f"{where}.{key}")):
                yield self.edge(item, f"{where}.{key}[{i}]", count, vertices)

        lanes = tuple(self.lane(e, w) for e, w in edges("lanes"))
        walls = tuple(e for e, _ in edges("walls"))
        doors = tuple(self.door(e, w) for e, w in edges("doors"))
        measurements = tuple(self.measurement(e, w) for e, w in edges("measurements"))
        human_lanes = tuple(HumanLane(e.start, e.end, e.params,
                                      self.number(e.params.get("width", 1.0), f"{w}.width",
                                                  positive=True))
                            for e, w in edges("human_lanes"))
        floors = tuple(self.floor(f, f"{where}.floors[{i}]", count) for i, f in
                       enumerate(self.sequence(level.get("floors"), f"{where}.floors")))
        models = tuple(self.model(m, f"{where}.models[{i}]") for i, m in
                       enumerate(self.sequence(level.get("models"), f"{where}.models")))
        fiducials = tuple(self.fiducial(f, f"{where}.fiducials[{i}]") for i, f in
                          enumerate(self.sequence(level.get("fiducials"),
                                                  f"{where}.fiducials")))
        elevation = self.number(level.get("elevation", 0.0), f"{where}.elevation")
        return Level(name, elevation, vertices, lanes, walls, doors, floors, models, fiducials,
                     measurements, human_lanes)

    def vertex(self, raw, where) -> Vertex:
        if not isinstance(raw, list) or len(raw) not in (4, 5):
            self.fail(where, f"expected [x, y, z, name] or [x, y, z, name, params], got "
                      f"{_short(raw)}")
        xy = (self.number(raw[0], f"{where}[0]"), self.number(raw[1], f"{where}[1]"))
        name = "" if raw[3] is None else self.text(raw[3], f"{where}[3]")
        params = self.params(raw[4], where) if len(raw) == 5 else MappingProxyType({})
        return Vertex(xy, name, params)

    def edge(self, raw, where, count, vertices) -> tuple[Edge, str]:
        if not isinstance(raw, list) or len(raw) not in (2, 3):
            self.fail(where, f"expected [start, end, params], got {_short(raw)}")
        ends = []
        for k in (0, 1):
            index = raw[k]
            if isinstance(index, bool) or not isinstance(index, int):
                self.fail(where, f"vertex {_short(index)} is not an index")
            if not 0 <= index < count:
                self.fail(where, f"vertex {index} does not exist (the level has {count} "
                          "vertices)")
            ends.append(index)
        if ends[0] == ends[1]:
            self.fail(where, f"joins vertex {ends[0]} to itself")
        params = self.params(raw[2], where) if len(raw) == 3 else MappingProxyType({})
        return Edge(ends[0], ends[1], params), where

    def lane(self, edge: Edge, where) -> Lane:
        graph = edge.params.get("graph_idx", 0)
        if not isinstance(graph, int) or isinstance(graph, bool) or graph < 0:
            self.fail(f"{where}.graph_idx", f"expected an int >= 0, got {_short(graph)}")
        two_way = edge.params.get("bidirectional", True)
        if not isinstance(two_way, bool):
            self.fail(f"{where}.bidirectional", f"expected a bool, got {_short(two_way)}")
        return Lane(edge.start, edge.end, edge.params, graph, two_way)

    def door(self, edge: Edge, where) -> Door:
        name = edge.params.get("name", "")
        if not isinstance(name, str) or not name:
            self.fail(f"{where}.name", "a door needs a name")
        return Door(edge.start, edge.end, edge.params, name, str(edge.params.get("type", "")))

    def measurement(self, edge: Edge, where) -> Measurement:
        if "distance" not in edge.params:
            self.fail(where, "a measurement needs a distance")
        distance = self.number(edge.params["distance"], f"{where}.distance", positive=True)
        return Measurement(edge.start, edge.end, edge.params, distance)

    def floor(self, raw, where, count) -> Floor:
        floor = self.mapping(raw, where)
        indices = self.sequence(floor.get("vertices"), f"{where}.vertices")
        for index in indices:
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < count:
                self.fail(f"{where}.vertices", f"vertex {_short(index)} does not exist (the "
                          f"level has {count} vertices)")
        if len(indices) < 3:
            self.fail(f"{where}.vertices", f"a floor needs at least 3 vertices, got "
                      f"{len(indices)}")
        return Floor(tuple(indices), self.params(floor.get("parameters"),
                                                 f"{where}.parameters"))

    def model(self, raw, where) -> Model:
        model = self.mapping(raw, where)
        for key in ("model_name", "x", "y"):
            if key not in model:
                self.fail(where, f"a model needs {key}")
        static = model.get("static", True)
        if not isinstance(static, bool):
            self.fail(f"{where}.static", f"expected true or false, got {_short(static)}")
        return Model(self.text(model.get("name", ""), f"{where}.name"),
                     self.text(model["model_name"], f"{where}.model_name"),
                     (self.number(model["x"], f"{where}.x"),
                      self.number(model["y"], f"{where}.y")),
                     self.number(model.get("z", 0.0), f"{where}.z"),
                     self.number(model.get("yaw", 0.0), f"{where}.yaw"), static)

    def fiducial(self, raw, where) -> Fiducial:
        if not isinstance(raw, list) or len(raw) != 3:
            self.fail(where, f"expected [x, y, name], got {_short(raw)}")
        return Fiducial(self.text(raw[2], f"{where}[2]"),
                        (self.number(raw[0], f"{where}[0]"), self.number(raw[1], f"{where}[1]")))

    def lift(self, name: str, raw, levels: Mapping[str, Level]) -> Lift:
        where = f"lifts.{name}"
        lift = self.mapping(raw, where)
        for key in ("x", "y", "width", "depth"):
            if key not in lift:
                self.fail(where, f"a lift needs {key}")
        doors = {}
        for door_name, door_raw in self.mapping(lift.get("doors"), f"{where}.doors").items():
            here = f"{where}.doors.{door_name}"
            door = self.mapping(door_raw, here)
            for key in ("x", "y"):  # the door's place on the cabin's faces
                if key not in door:
                    self.fail(here, f"a lift door needs {key}")
            doors[str(door_name)] = LiftDoor(
                str(door_name), (self.number(door["x"], f"{here}.x"),
                                 self.number(door["y"], f"{here}.y")),
                self.number(door.get("width"), f"{here}.width", positive=True),
                int(self.number(door.get("door_type", 2), f"{here}.door_type")))
        if not doors:
            self.fail(f"{where}.doors", "a lift needs at least one cabin door")
        level_doors = {}
        for level, names in self.mapping(lift.get("level_doors"),
                                         f"{where}.level_doors").items():
            here = f"{where}.level_doors.{level}"
            if str(level) not in levels:
                self.fail(here, f"{level!r} is not a level (levels: {', '.join(levels)})")
            names = tuple(self.text(n, here) for n in self.sequence(names, here))
            for door_name in names:
                if door_name not in doors:
                    self.fail(here, f"no cabin door {door_name!r} (doors: {', '.join(doors)})")
            level_doors[str(level)] = names
        if not any(level_doors.values()):
            self.fail(f"{where}.level_doors", "the lift opens its doors on no level")
        served = list(level_doors)
        floors = {}
        for key, default in (("reference_floor_name", served[0]),
                             ("initial_floor_name", served[0]),
                             ("lowest_floor", served[0]), ("highest_floor", served[-1])):
            value = self.text(lift.get(key, default), f"{where}.{key}")
            if value not in levels:
                self.fail(f"{where}.{key}", f"{value!r} is not a level (levels: "
                          f"{', '.join(levels)})")
            floors[key] = value
        return Lift(name, (self.number(lift["x"], f"{where}.x"),
                           self.number(lift["y"], f"{where}.y")),
                    self.number(lift.get("yaw", 0.0), f"{where}.yaw"),
                    self.number(lift["width"], f"{where}.width", positive=True),
                    self.number(lift["depth"], f"{where}.depth", positive=True),
                    MappingProxyType(doors), MappingProxyType(level_doors),
                    floors["reference_floor_name"], floors["initial_floor_name"],
                    floors["lowest_floor"], floors["highest_floor"])

    # --- Whole-building checks ------------------------------------------------------------

    def check_door_names(self, levels: Mapping[str, Level]) -> None:
        seen = {}
        for level in levels.values():
            for i, door in enumerate(level.doors):
                where = f"levels.{level.name}.doors[{i}]"
                if door.name in seen:
                    self.fail(f"{where}.name", f"{door.name!r} is already the name of "
                              f"{seen[door.name]}")
                seen[door.name] = where

    def check_geometry(self, level: Level) -> None:
        """Checks in metres: no zero-length wall or lane, every door on a wall."""
        where = f"levels.{level.name}"
        for key in ("walls", "lanes"):
            for i, edge in enumerate(getattr(level, key)):
                a, b = level.point(edge.start), level.point(edge.end)
                if math.dist(a, b) < 1e-6:
                    self.fail(f"{where}.{key}[{i}]", f"vertices {edge.start} and {edge.end} "
                              f"are both at {_rounded(a)}: zero length")
        for i, door in enumerate(level.doors):
            a, b = level.point(door.start), level.point(door.end)
            if math.dist(a, b) < 1e-6:
                self.fail(f"{where}.doors[{i}]", f"door {door.name!r} has zero width")
            if not (_on_a_wall(level, a) or _on_a_wall(level, b)):
                self.fail(f"{where}.doors[{i}]", f"door {door.name!r} from {_rounded(a)} to "
                          f"{_rounded(b)} is not on a wall (neither end touches one)")


def _on_a_wall(level: Level, point) -> bool:
    """Whether ``point`` (m) lies on one of ``level``'s walls, within
    ``DOOR_ON_WALL_TOLERANCE`` (a wall's end vertices included)."""
    if not level.walls:
        return False
    starts = [level.point(wall.start) for wall in level.walls]
    ends = [level.point(wall.end) for wall in level.walls]
    return bool(segment_distances(point, starts, ends).min() <= DOOR_ON_WALL_TOLERANCE)


def _moved(level: Level, transform) -> Level:
    """``level`` with every position mapped by ``transform`` (raw units to metres)."""
    return replace(
        level,
        vertices=tuple(replace(v, xy=transform.point(v.xy)) for v in level.vertices),
        models=tuple(replace(m, xy=transform.point(m.xy), yaw=m.yaw + transform.rotation,
                             z=m.z + level.elevation) for m in level.models),
        fiducials=tuple(replace(f, xy=transform.point(f.xy)) for f in level.fiducials))


def _rounded(point) -> list[float]:
    return [round(point[0], 3) + 0.0, round(point[1], 3) + 0.0]  # + 0.0: no -0.0


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
