"""Drawing a building run across levels in Meshcat with its levels stacked at their
elevations (``world.levels_view: stacked``).

The simulation keeps the levels side by side in one plane (``world/levels.py``); this view
only moves what it draws: a point of level k at (x, y) in the combined plane is drawn at
(x - offset_k, y, elevation_k), so the levels stand above each other as in the building.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import Value
from pydrake.geometry import Box, Cylinder, Meshcat, Rgba
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.navigation.lift_bank import LiftSpec
from mrta_drake.payloads import ROBOT_STATE_SIZE, HumanStates, LiftState, LiftStatus
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.levels import LevelLayout
from mrta_drake.world.plant import (
    FURNITURE_COLOR,
    HUMAN_COLOR,
    HUMAN_HEIGHT,
    ROBOT_COLORS,
    ROBOT_HEIGHT,
    WALL_COLOR,
)

FLOOR_COLOR = Rgba(0.85, 0.85, 0.9, 0.35)
CABIN_COLOR = Rgba(0.2, 0.7, 0.9, 0.45)
CABIN_HEIGHT = 2.2  # m
FLOOR_THICKNESS = 0.05  # m
WALL_HEIGHT = 1.0  # m: walls and furniture drawn at most this high, the floor below seen


@dataclass(frozen=True)
class StackedView:
    """The viewing transform of the stacked levels: the combined plane's points to 3D
    points with each level at its elevation (world frame, m)."""

    layout: LevelLayout

    def point(self, xy, z: float = 0.0, level: str | None = None) -> tuple[float, float, float]:
        """Where the point ``xy`` of the combined plane, ``z`` m above its floor, is drawn:
        on ``level`` if given, else the level whose bounds hold it (a point on none stays
        where it is)."""
        level = level or self.layout.level_of(xy)
        if level is None:
            return (float(xy[0]), float(xy[1]), float(z))
        placement = self.layout.placement(level)
        return (float(xy[0]) - placement.offset, float(xy[1]), float(z) + placement.elevation)

    def points(self, xyz: np.ndarray) -> np.ndarray:
        """``point`` of each column of a (3, K) array of [x, y, z]."""
        return np.array([self.point(p[:2], p[2]) for p in np.asarray(xyz, float).T]).T \
            .reshape(3, -1)

    def cabin_elevation(self, lift: LiftSpec, status: LiftStatus, t: float) -> float:
        """The floor (m) of ``lift``'s cabin at time ``t`` (s): its level's elevation, or,
        while it moves, in between at a steady speed."""
        elevations = {stop.level: stop.elevation for stop in lift.stops}
        if status.trip is None:
            return elevations[status.level]
        start, end, t0, t1 = status.trip
        share = 1.0 if t1 <= t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        return elevations[start] + share * (elevations[end] - elevations[start])


class LevelsView(LeafSystem):
    """Draws the levels of ``floor_plan`` stacked (``StackedView``) in ``meshcat``: once, each
    level's floor, walls and furniture (at most ``WALL_HEIGHT`` high); at ``rate_hz``
    (publish events only) the robots, people and lift cabins, cabins moving between floors
    with their riders.

    .. pydrake_system::

        name: LevelsView
        input_ports:
        - robot_state
        - human_states (optional)
        - lift_state (optional)

    Inputs: ``robot_state`` (4N, ``[x, y, theta, v]`` per robot, world frame, m, rad, m/s),
    ``human_states`` (HumanStates), ``lift_state`` (LiftState)."""

    def __init__(self, meshcat: Meshcat, floor_plan: FloorPlan, layout: LevelLayout,
                 lifts: Sequence[LiftSpec], robots: Sequence[tuple[str, float]],
                 people: Sequence[tuple[str, float]] = (), *, rate_hz: float,
                 prefix: str = "levels"):
        super().__init__()
        self._meshcat, self._prefix = meshcat, prefix
        self._view = StackedView(layout)
        self._lifts = tuple(lifts)
        self._robots = tuple(name for name, _ in robots)
        self._people = tuple(name for name, _ in people)
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * len(self._robots)))
        self._humans = self.DeclareAbstractInputPort("human_states", Value[object](HumanStates()))
        self._lift_state = self.DeclareAbstractInputPort("lift_state", Value[object](LiftState()))
        self.DeclarePeriodicPublishEvent(1.0 / rate_hz, 0.0, self._draw)
        self._draw_building(floor_plan, layout)
        for name, radius in robots:
            r, g, b = ROBOT_COLORS[self._robots.index(name) % len(ROBOT_COLORS)]
            meshcat.SetObject(f"{prefix}/robots/{name}", Cylinder(radius, ROBOT_HEIGHT),
                              Rgba(r, g, b))
        for name, radius in people:
            meshcat.SetObject(f"{prefix}/people/{name}", Cylinder(radius, HUMAN_HEIGHT),
                              Rgba(*HUMAN_COLOR))

    @property
    def view(self) -> StackedView:
        return self._view

    def _draw_building(self, floor_plan: FloorPlan, layout: LevelLayout) -> None:
        mc, prefix = self._meshcat, self._prefix
        for placement in layout.levels:
            x0, x1, y0, y1 = placement.bounds
            path = f"{prefix}/floors/{placement.name}"
            mc.SetObject(path, Box(x1 - x0, y1 - y0, FLOOR_THICKNESS), FLOOR_COLOR)
            mc.SetTransform(path, RigidTransform(self._view.point(
                (0.5 * (x0 + x1), 0.5 * (y0 + y1)), -0.5 * FLOOR_THICKNESS, placement.name)))
        tall = floor_plan.wall_height - 1e-6
        for k, box in enumerate(floor_plan.obstacles.boxes):
            path = f"{prefix}/building/box_{k}"
            color = WALL_COLOR if box.height >= tall else FURNITURE_COLOR
            height = min(box.height, WALL_HEIGHT)
            mc.SetObject(path, Box(*box.size, height), Rgba(*color))
            mc.SetTransform(path, RigidTransform(RollPitchYaw(0.0, 0.0, box.yaw), self._view
                                                 .point(box.center, 0.5 * height,
                                                        _level_of(box.name))))
        for k, cylinder in enumerate(floor_plan.obstacles.cylinders):
            path = f"{prefix}/building/cylinder_{k}"
            height = min(cylinder.height, WALL_HEIGHT)
            mc.SetObject(path, Cylinder(cylinder.radius, height), Rgba(*FURNITURE_COLOR))
            mc.SetTransform(path, RigidTransform(self._view.point(
                cylinder.center, 0.5 * height, _level_of(cylinder.name))))
        for lift in self._lifts:
            size = (lift.width or 1.0, lift.depth or 1.0)
            mc.SetObject(f"{prefix}/cabins/{lift.name}", Box(*size, CABIN_HEIGHT), CABIN_COLOR)

    def _draw(self, context) -> None:
        t = context.get_time()
        mc, prefix = self._meshcat, self._prefix
        lifts = (self._lift_state.Eval(context) if self._lift_state.HasValue(context)
                 else LiftState())
        riding = {}
        for lift in self._lifts:
            status = lifts.lift(lift.name) or LiftStatus(lift.name, lift.initial_level)
            z = self._view.cabin_elevation(lift, status, t)
            stop = lift.stop(status.level)
            x, y, _ = self._view.point(stop.middle, 0.0, stop.level)
            mc.SetTransform(f"{prefix}/cabins/{lift.name}", RigidTransform(
                RollPitchYaw(0.0, 0.0, lift.yaw), [x, y, z + 0.5 * CABIN_HEIGHT]), t)
            if status.trip is not None and status.phase == "travel":
                riding.update({name: z for name in status.riders})
        states = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        for name, (x, y, theta, _) in zip(self._robots, states, strict=True):
            px, py, pz = self._view.point((x, y), 0.5 * ROBOT_HEIGHT)
            if name in riding:
                pz = riding[name] + 0.5 * ROBOT_HEIGHT
            mc.SetTransform(f"{prefix}/robots/{name}", RigidTransform(
                RollPitchYaw(0.0, 0.0, theta), [px, py, pz]), t)
        if self._people and self._humans.HasValue(context):
            humans = self._humans.Eval(context)
            for name, xy in zip(humans.names, humans.positions, strict=True):
                mc.SetTransform(f"{prefix}/people/{name}", RigidTransform(
                    self._view.point(xy, 0.5 * HUMAN_HEIGHT)), t)


def _level_of(name: str) -> str | None:
    """The level an obstacle named ``<level>/<name>`` stands on."""
    return name.split("/", 1)[0] if "/" in name else None
