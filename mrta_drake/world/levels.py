"""Several levels of a building side by side in one plane.

Level k's plan is shifted along x so that it starts ``gap`` m east of level k - 1's east
edge (levels in building order, the first unshifted). The gap keeps robots, people, wall
rays and clusters of different levels out of each other's reach, so every block works on
the one combined plan unchanged. ``LevelLayout`` is the one place that knows the offsets.

Metres, world frame (x east, y north); elevations in m above the ground level.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from mrta_drake.errors import InputError
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles

MIN_LEVEL_GAP = 30.0  # m: more than the cluster radius, ray range and people's reach


@dataclass(frozen=True)
class LevelPlacement:
    """Level ``name`` at ``elevation`` m, drawn shifted by ``offset`` m along x; ``bounds``
    (x_min, x_max, y_min, y_max) of its shifted plan, m."""

    name: str
    offset: float
    elevation: float
    bounds: tuple[float, float, float, float]


@dataclass(frozen=True)
class LevelLayout:
    """Where each level lies in the combined plane, in building order."""

    levels: tuple[LevelPlacement, ...]

    @classmethod
    def side_by_side(cls, plans: Sequence[tuple[str, float, tuple]], gap: float = MIN_LEVEL_GAP
                     ) -> "LevelLayout":
        """The layout of levels given as (name, elevation m, unshifted bounds) in building
        order, ``gap`` m apart (at least ``MIN_LEVEL_GAP``)."""
        if not gap >= MIN_LEVEL_GAP:
            raise InputError(None, "level_gap", f"must be >= {MIN_LEVEL_GAP:g} m, got {gap}")
        placements, east = [], None
        for name, elevation, (x0, x1, y0, y1) in plans:
            offset = 0.0 if east is None else east + gap - x0
            placements.append(LevelPlacement(name, offset, float(elevation),
                                             (x0 + offset, x1 + offset, y0, y1)))
            east = x1 + offset
        return cls(tuple(placements))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.levels)

    def placement(self, name: str) -> LevelPlacement:
        """Level ``name``'s placement (KeyError if unknown)."""
        for placement in self.levels:
            if placement.name == name:
                return placement
        raise KeyError(name)

    def to_world(self, level: str, xy) -> tuple[float, float]:
        """A point (m) of ``level``'s own plan in the combined plane."""
        return (float(xy[0]) + self.placement(level).offset, float(xy[1]))

    def level_of(self, xy) -> str | None:
        """The level whose shifted bounds hold the point ``xy`` (m), else None."""
        for placement in self.levels:
            x0, x1, y0, y1 = placement.bounds
            if x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1:
                return placement.name
        return None

    def moved(self, xy, from_level: str, to_level: str) -> tuple[float, float]:
        """The point of ``to_level`` above or below ``xy`` (m) of ``from_level``."""
        shift = self.placement(to_level).offset - self.placement(from_level).offset
        return (float(xy[0]) + shift, float(xy[1]))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """The box (m) around every level."""
        boxes = [p.bounds for p in self.levels]
        return (min(b[0] for b in boxes), max(b[1] for b in boxes),
                min(b[2] for b in boxes), max(b[3] for b in boxes))


def combined_floor_plan(name: str, plans: Mapping[str, FloorPlan], layout: LevelLayout,
                        source: str = "") -> FloorPlan:
    """One floor plan of the level ``plans`` (by level name) placed as in ``layout``:
    obstacles and places named ``<level>/<name>``, each level's floors (its plan's, else
    its bounds) shifted with it, so that the gaps between the levels are no floor."""
    boxes, cylinders, places, floors = [], [], {}, []
    for level, plan in plans.items():
        offset = layout.placement(level).offset
        x0, x1, y0, y1 = plan.bounds
        floors += [tuple((x + offset, y) for x, y in floor) for floor in
                   plan.floors or [((x0, y0), (x1, y0), (x1, y1), (x0, y1))]]
        obstacles = plan.obstacles
        boxes += [Box(f"{level}/{b.name}", (b.center[0] + offset, b.center[1]), b.size, b.yaw,
                      b.height) for b in obstacles.boxes]
        cylinders += [Cylinder(f"{level}/{c.name}", (c.center[0] + offset, c.center[1]),
                               c.radius, c.height) for c in obstacles.cylinders]
        places.update({f"{level}/{place}": layout.to_world(level, xy)
                       for place, xy in plan.places.items()})
    wall_height = max(plan.wall_height for plan in plans.values())
    return FloorPlan(name=name, bounds=layout.bounds, wall_height=wall_height,
                     obstacles=Obstacles(tuple(boxes), tuple(cylinders)), places=places,
                     source=source, floors=tuple(floors))
