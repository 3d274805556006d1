"""The floor-plan file format (our YAML for one building floor) as frozen dataclasses.

``load_floor_plan`` reads a file into ``FloorPlanFile`` with the typed loader
(``scenario.typed_yaml.load_typed``): the types say which fields exist and what they hold,
each class's ``__post_init__`` checks the rest, raising ``InputError`` with the field relative
to itself (the loader puts the file and the path in front: ``walls[3].doors[0].width``).

World frame: x east, y north, z up; lengths in metres, angles in radians (counterclockwise
from +x).
"""

import math
from dataclasses import dataclass, field

from mrta_drake.errors import InputError

Point = tuple[float, float]  # [x, y], m, world frame

_EPS = 1e-9


def check_number(value: float | tuple[float, ...], where: str, positive: bool = False) -> None:
    """Raise InputError unless ``value`` (a number or a tuple of them) is finite, and > 0
    with ``positive``; ``where`` names the field."""
    items = enumerate(value) if isinstance(value, tuple) else [(None, value)]
    for i, number in items:
        here = where if i is None else f"{where}[{i}]"
        if not math.isfinite(number):
            raise InputError(None, here, f"must be finite, got {number!r}")
        if positive and number <= 0.0:
            raise InputError(None, here, f"must be > 0, got {number:g}")


def check_numbers(spec, finite: tuple[str, ...] = (), positive: tuple[str, ...] = ()) -> None:
    """``check_number`` on the fields of ``spec`` named in ``finite`` and in ``positive``."""
    for name in finite:
        check_number(getattr(spec, name), name)
    for name in positive:
        check_number(getattr(spec, name), name, positive=True)


def _check_name(name: str | None) -> None:
    if name is not None and not name:
        raise InputError(None, "name", "expected a non-empty string, got ''")


@dataclass(frozen=True)
class DoorSpec:
    """A gap in a wall, ``width`` m long along it, centred on the projection of ``center``
    onto the wall's centre line; ``center`` may be off that line by at most the wall's
    thickness, and the gap must lie within the wall."""

    center: Point
    width: float

    def __post_init__(self):
        check_numbers(self, finite=("center",), positive=("width",))


@dataclass(frozen=True)
class WallSpec:
    """A straight wall along its centre line ``from`` -> ``to``, ``thickness`` wide (default:
    the plan's ``wall_thickness``), with ``doors``. ``name`` defaults to ``wall<i>`` (its
    index in ``walls``)."""

    from_: Point
    to: Point
    name: str | None = None
    thickness: float | None = None
    doors: list[DoorSpec] = field(default_factory=list)

    def __post_init__(self):
        _check_name(self.name)
        check_number(self.from_, "from")
        check_number(self.to, "to")
        if self.thickness is not None:
            check_number(self.thickness, "thickness", positive=True)
        if self.length <= _EPS:
            raise InputError(None, "to", f"{list(self.to)} equals 'from': a wall needs length")

    @property
    def length(self) -> float:
        """m."""
        return math.dist(self.from_, self.to)

    @property
    def direction(self) -> Point:
        """The unit vector from ``from`` to ``to``."""
        return ((self.to[0] - self.from_[0]) / self.length,
                (self.to[1] - self.from_[1]) / self.length)

    def door_gaps(self, thickness: float) -> list[tuple[float, float]]:
        """Each door's gap as (start, end) distances along the wall from ``from`` (m), in
        door order, for a wall ``thickness`` m wide; InputError (field ``doors[k]...``) for
        a door wider than the wall, off it, past its ends or overlapping another door."""
        a, length = self.from_, self.length
        ux, uy = self.direction
        gaps = []
        for k, door in enumerate(self.doors):
            where = f"doors[{k}]"
            if door.width > length + _EPS:
                raise InputError(None, f"{where}.width", f"{door.width:g} m is wider than its "
                                 f"wall ({length:g} m long)")
            dx, dy = door.center[0] - a[0], door.center[1] - a[1]
            offset = abs(-uy * dx + ux * dy)
            along = ux * dx + uy * dy
            center = list(door.center)
            if offset > thickness + _EPS:
                raise InputError(None, f"{where}.center", f"{center} is {offset:.3g} m off its "
                                 f"wall from {list(a)} to {list(self.to)} (at most {thickness:g})")
            lo, hi = along - 0.5 * door.width, along + 0.5 * door.width
            if lo < -_EPS or hi > length + _EPS:
                raise InputError(None, f"{where}.center", f"{center}: the door spans "
                                 f"{lo:.3g}..{hi:.3g} m along its wall, which is {length:g} m long")
            for other, (other_lo, other_hi) in enumerate(gaps):
                if lo < other_hi - _EPS and other_lo < hi - _EPS:
                    raise InputError(None, f"{where}.center",
                                     f"{center}: the door overlaps doors[{other}]")
            gaps.append((lo, hi))
        return gaps


@dataclass(frozen=True)
class BoxSpec:
    """A box standing on the floor: ``center`` [x, y], ``size`` [along its x, along its y],
    ``yaw`` of its x axis from +x, ``height``."""

    center: Point
    size: Point
    yaw: float = 0.0
    height: float = 1.0

    def __post_init__(self):
        check_numbers(self, finite=("center", "yaw"), positive=("size", "height"))


@dataclass(frozen=True)
class CylinderSpec:
    """An upright cylinder: ``center`` [x, y], ``radius``, ``height``."""

    center: Point
    radius: float
    height: float = 1.0

    def __post_init__(self):
        check_numbers(self, finite=("center",), positive=("radius", "height"))


@dataclass(frozen=True)
class ArcSpec:
    """A curved band (a reception desk), built as a chain of ``segments`` boxes: centre-line
    ``radius`` around ``center``, ``thickness`` wide, running counterclockwise from angle
    ``start`` to ``end`` (at most one full turn); consecutive boxes meet at the outer edge."""

    center: Point
    radius: float
    thickness: float
    start: float
    end: float
    segments: int = 8
    height: float = 1.0

    def __post_init__(self):
        check_numbers(self, finite=("center", "start", "end"),
                      positive=("radius", "thickness", "height"))
        if self.thickness >= 2.0 * self.radius:
            raise InputError(None, "thickness", f"{self.thickness:g} must be less than twice "
                             f"the radius ({self.radius:g})")
        if not 0.0 < self.end - self.start <= 2.0 * math.pi + _EPS:
            raise InputError(None, "end", f"{self.end:g} must be in (start, start + 2 pi], "
                             f"start is {self.start:g}")
        if self.segments < 1:
            raise InputError(None, "segments", f"must be >= 1, got {self.segments}")


SHAPES = ("box", "cylinder", "arc")


@dataclass(frozen=True)
class FurnitureSpec:
    """One piece of furniture: a ``name`` and exactly one shape, ``box``, ``cylinder`` or
    ``arc``."""

    name: str
    box: BoxSpec | None = None
    cylinder: CylinderSpec | None = None
    arc: ArcSpec | None = None

    def __post_init__(self):
        _check_name(self.name)
        given = [shape for shape in SHAPES if getattr(self, shape) is not None]
        if len(given) != 1:
            raise InputError(None, None, f"needs exactly one of {', '.join(SHAPES)}, got "
                             f"{given or 'none'}")

    @property
    def kind(self) -> str:
        """Which shape it is: box, cylinder or arc."""
        return next(shape for shape in SHAPES if getattr(self, shape) is not None)


@dataclass(frozen=True)
class FloorPlanFile:
    """A floor-plan file: one floor, authored by hand. Example::

        name: hospital_floor1                  # required
        bounds: [x_min, x_max, y_min, y_max]   # required; the mapped area
        wall_height: 2.5                       # optional, default 2.5
        wall_thickness: 0.15                   # optional default for every wall
        walls:
          - name: lobby_south                  # optional; default wall<i>
            from: [x, y]                       # centre-line end points
            to: [x, y]
            thickness: 0.15                    # optional, default wall_thickness
            doors:                             # each door is a gap in the wall
              - {center: [x, y], width: 1.4}   # center lies on the wall; width along it
        furniture:                             # each item has exactly one shape
          - {name: bed_1, box: {center: [x, y], size: [sx, sy], yaw: 0.0, height: 0.6}}
          - {name: planter, cylinder: {center: [x, y], radius: 0.3, height: 1.0}}
          - name: reception                    # an arc, built as a chain of boxes
            arc: {center: [x, y], radius: 3.3, thickness: 0.4, start: 0.0, end: 3.14,
                  segments: 8, height: 1.1}
        places: {lobby: [0.0, 2.2]}            # named points

    Walls become one box per piece between doors, ``thickness`` wide and ``wall_height``
    tall. A piece that reaches an end of its wall is extended by half the thickness there,
    so walls that meet at a shared end point close their corner. Furniture is ``height``
    1.0 m tall unless given. Wall ends, furniture centres and places lie within ``bounds``;
    wall and furniture names are unique.
    """

    name: str
    bounds: tuple[float, float, float, float]
    wall_height: float = 2.5
    wall_thickness: float = 0.15
    walls: list[WallSpec] = field(default_factory=list)
    furniture: list[FurnitureSpec] = field(default_factory=list)
    places: dict[str, Point] = field(default_factory=dict)

    def __post_init__(self):
        _check_name(self.name)
        check_number(self.bounds, "bounds")
        x_min, x_max, y_min, y_max = self.bounds
        if not (x_min < x_max and y_min < y_max):
            raise InputError(None, "bounds", f"need x_min < x_max and y_min < y_max, got "
                             f"{list(self.bounds)}")
        check_numbers(self, positive=("wall_height", "wall_thickness"))
        names: dict[str, str] = {}  # wall or furniture name -> where it was defined

        def claim(name: str, where: str) -> None:
            if name in names:
                raise InputError(None, f"{where}.name",
                                 f"'{name}' is already used by {names[name]}")
            names[name] = where

        for i, wall in enumerate(self.walls):
            where = f"walls[{i}]"
            self._check_inside(wall.from_, f"{where}.from")
            self._check_inside(wall.to, f"{where}.to")
            try:
                wall.door_gaps(self.thickness_of(wall))
            except InputError as error:
                raise error.nested(None, where) from None
            claim(self.wall_name(i), where)
        for i, item in enumerate(self.furniture):
            where = f"furniture[{i}]"
            self._check_inside(getattr(item, item.kind).center, f"{where}.{item.kind}.center")
            claim(item.name, where)
        for name, point in self.places.items():
            self._check_inside(point, f"places.{name}")

    def _check_inside(self, point: Point, where: str) -> None:
        x_min, x_max, y_min, y_max = self.bounds
        if not (x_min - _EPS <= point[0] <= x_max + _EPS
                and y_min - _EPS <= point[1] <= y_max + _EPS):
            raise InputError(None, where, f"{list(point)} is outside bounds {list(self.bounds)}")

    def wall_name(self, index: int) -> str:
        """The name of ``walls[index]``: its own, or ``wall<index>``."""
        return self.walls[index].name or f"wall{index}"

    def thickness_of(self, wall: WallSpec) -> float:
        """The wall's thickness (m): its own, or the plan's ``wall_thickness``."""
        return self.wall_thickness if wall.thickness is None else wall.thickness
